"""Every mutant of tests/mutation/ still names a text that occurs exactly once in its file, and
every test file a mutant names exists (a missing file makes pytest fail, which the mutation
tool would count as a kill). A source edit that moves a mutated line fails here, in the
suite, instead of at the next mutation run."""
import importlib.util
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
MUT = ROOT / 'tests' / 'mutation'


def test_every_old_text_is_found_once():
    r = subprocess.run([sys.executable, str(MUT / 'mutate.py'), 'all', '--check'],
                       capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    assert 'every old text found once' in r.stdout


def test_every_named_test_file_exists():
    sys.path.insert(0, str(MUT))
    try:
        missing = []
        for path in sorted(MUT.glob('*.py')):
            if path.stem in ('mutate', '__init__'):
                continue
            spec = importlib.util.spec_from_file_location(f'mutants_{path.stem}', path)
            mod = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(mod)
            for args in [mod.TESTS] + [m.tests for m in mod.MUTANTS]:
                for a in args:
                    if a.startswith('tests/') and not (ROOT / a.split('::')[0]).exists():
                        missing.append((path.stem, a))
        assert not missing, missing
    finally:
        sys.path.remove(str(MUT))
