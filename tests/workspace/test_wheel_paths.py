"""scripts/fix_ros_wheel_paths.py: the ros-jazzy-* wheels' CMake exports point at this
Python after it runs, a second run changes nothing, and a path that does not exist here fails
loudly; the real venv has no build-container path left."""
import pathlib
import subprocess
import sys
import sysconfig

ROOT = pathlib.Path(__file__).resolve().parents[2]
SCRIPT = ROOT / 'scripts' / 'fix_ros_wheel_paths.py'
VER = f'python{sys.version_info[0]}.{sys.version_info[1]}'


def _export(prefix: pathlib.Path, pkg: str, dirs: str) -> pathlib.Path:
    d = prefix / 'share' / pkg / 'cmake'
    d.mkdir(parents=True)
    f = d / f'export_{pkg}__rosidl_generator_pyExport.cmake'
    f.write_text('set_target_properties(x PROPERTIES\n'
                 f'  INTERFACE_INCLUDE_DIRECTORIES "{dirs}"\n)\n')
    return f


def _run(prefix):
    return subprocess.run([sys.executable, str(SCRIPT), str(prefix)], capture_output=True,
                          text=True, timeout=60)


def test_rewrites_the_build_container_paths_once(tmp_path):
    site = pathlib.Path(sysconfig.get_paths(vars={'base': str(tmp_path),
                                                  'platbase': str(tmp_path)})['purelib'])
    (site / 'numpy' / '_core' / 'include').mkdir(parents=True)
    f = _export(tmp_path, 'std_msgs',
                f'/opt/python/cp311-cp311/include/{VER};'
                f'/opt/python/cp311-cp311/lib/{VER}/site-packages/numpy/_core/include')
    first = _run(tmp_path)
    assert first.returncode == 0, first.stderr
    text = f.read_text()
    assert '/opt/python' not in text
    assert sysconfig.get_paths()['include'] in text
    assert str(site / 'numpy' / '_core' / 'include') in text
    assert '1 CMake files' in first.stdout
    second = _run(tmp_path)
    assert second.returncode == 0 and second.stdout == '' and f.read_text() == text


def test_a_path_missing_here_fails_loudly(tmp_path):
    _export(tmp_path, 'geometry_msgs',
            f'/opt/python/cp311-cp311/lib/{VER}/site-packages/not_installed/include')
    res = _run(tmp_path)
    assert res.returncode == 1 and 'not_installed' in res.stderr


def test_the_project_venv_has_no_build_container_path_left():
    share = pathlib.Path(sys.prefix) / 'share'
    left = [p for p in share.glob('*/cmake/*.cmake') if '/opt/python/' in p.read_text()]
    assert left == []
