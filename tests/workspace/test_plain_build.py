"""A plain `colcon build` (no --symlink-install) into a fresh directory works: the scenarios,
the launch file and the shipped force-estimator models are installed to share/<pkg>/ and
found through the ament index, and a short scenario runs from that install alone (not from
the source tree, not from ros_ws/install). catheter_interfaces comes from ros_ws/install as
an underlay (the normal ROS 2 workflow; its build is the set-up's, ~10 s of C compilation)."""
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def _clean_env(tmp: pathlib.Path) -> dict:
    """The venv and nothing of this checkout's workspace (no PYTHONPATH, no ros_ws/install)."""
    venv = pathlib.Path(sys.prefix)
    keep = ('HOME', 'LANG', 'LC_ALL', 'TMPDIR', 'ROS_DOMAIN_ID', 'ROS_AUTOMATIC_DISCOVERY_RANGE',
            'RMW_IMPLEMENTATION')
    env = {k: os.environ[k] for k in keep if k in os.environ}
    env.update(PATH=f'{venv}/bin:/usr/bin:/bin', VIRTUAL_ENV=str(venv),
               AMENT_PREFIX_PATH=str(venv), PYTHONNOUSERSITE='1')
    return env


@pytest.mark.slow
@pytest.mark.ros
def test_plain_colcon_build_installs_data_and_runs_a_scenario(tmp_path):
    iface = ROOT / 'ros_ws' / 'install' / 'catheter_interfaces' / 'share' / \
        'catheter_interfaces' / 'package.bash'
    assert iface.exists(), 'run scripts/setup.sh first'
    bag = tmp_path / 'smoke.mcap'
    probe = ('import catheter_bringup.scenario as s, force_estimator.models as m, '
             'catheter_interfaces.msg as i; '
             "print(s.__file__); print(s.config_dir()); print(m.shipped_model_path('blazer-svr'));"
             ' print(i.__file__)')
    script = f"""
set -e
. "{iface}"
cd "{tmp_path}"
colcon --log-base log build --base-paths "{ROOT}/src" --build-base build --install-base install \
  --packages-up-to catheter_bringup --packages-skip catheter_interfaces \
  --event-handlers console_cohesion- summary- > build.txt 2>&1 || {{ tail -50 build.txt; exit 3; }}
. install/local_setup.bash
python -c "{probe}"
cd /
install_dir="{tmp_path}/install"
"$install_dir/catheter_bringup/lib/catheter_bringup/run_scenario" smoke --duration 0.3 \
  --bag "{bag}" --quiet
"""
    proc = subprocess.run(['bash', '-c', script], env=_clean_env(tmp_path), cwd=tmp_path,
                          capture_output=True, text=True, timeout=600)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out
    lines = proc.stdout.splitlines()
    install = tmp_path / 'install'
    module, cfg, model, iface_mod = lines[:4]
    assert module.startswith(str(install / 'catheter_bringup' / 'lib')), module
    share = install / 'catheter_bringup' / 'share' / 'catheter_bringup'
    assert cfg == str(share / 'config')
    assert model.startswith(str(install / 'force_estimator')), model
    assert iface_mod.startswith(str(ROOT / 'ros_ws' / 'install' / 'catheter_interfaces'))
    # a plain build: copies, not links into the source tree
    smoke = share / 'config' / 'smoke.yaml'
    assert smoke.is_file() and not smoke.is_symlink()
    assert (share / 'launch' / 'scenario.launch.py').is_file()
    models = install / 'force_estimator' / 'share' / 'force_estimator' / 'models'
    assert sorted(p.name for p in models.glob('*.npz')) == ['blazer-mlp.npz', 'blazer-svr.npz']
    assert 'scenario smoke: complete' in out, out
    assert bag.stat().st_size > 10_000
