"""Hand-made mutation check: apply textual mutations to the source one at a time, run a pytest
selection against each, restore the file, and report which mutants survive.

    python tests/mutation/mutate.py fam            # every mutant of tests/mutation/fam.py
    python tests/mutation/mutate.py fam -k M03     # mutants whose id contains 'M03'
    python tests/mutation/mutate.py --list         # the mutant lists there are
    python tests/mutation/mutate.py all            # every list; a table per package and the total
    python tests/mutation/mutate.py all --check    # only check that every old text occurs once

A mutant list is a module ``tests/mutation/<name>.py`` that defines

    TESTS = ['tests/fam_solver', '-k', 'not node']     # pytest arguments for this list
    MUTANTS = [Mutant('M01', 'src/pkg/pkg/mod.py', 'old text', 'new text', 'what it breaks'), ...]

A mutant may name its own pytest arguments (``tests=(...)``), e.g. the one test file that
kills it quickly where the whole selection would crawl through slow failures first.

A mutant that survives and is known to be harmless (equivalent in every outcome the package
promises) carries the reason in ``harmless=``; it is reported as such, not as a failure.

``old`` must occur exactly once in the file. Safety: a file with uncommitted changes is refused
(``git diff --quiet``), every mutation is undone in a ``finally`` (also on Ctrl-C), and the
file's bytes are checked to be the original afterwards. Each pytest run gets a fresh bytecode
cache directory (PYTHONPYCACHEPREFIX), so no stale .pyc of the original or of an earlier mutant
can be imported. The selection must pass unmutated first (baseline).

Prints one line per mutant (killed / SURVIVED, seconds) and a summary (for ``all``: a table
per package, counted by the mutated file's src/<package>, and the total); exit status 0 when
every mutant was killed or is a known harmless survivor, 1 otherwise, 2 on a usage or
baseline error.
"""
from __future__ import annotations

import argparse
import importlib.util
import os
import pathlib
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass

ROOT = pathlib.Path(__file__).resolve().parents[2]
HERE = pathlib.Path(__file__).resolve().parent


@dataclass(frozen=True)
class Mutant:
    id: str
    file: str           # path relative to the repository root
    old: str            # text replaced (must occur exactly once)
    new: str
    why: str            # the property the mutant breaks
    harmless: str = ''  # for a known survivor: why it does no harm (an equivalent mutant)
    tests: tuple = ()   # pytest arguments for this mutant instead of the list's TESTS


def load_list(name: str):
    path = HERE / f'{name}.py'
    if not path.is_file() or name == 'mutate':
        raise SystemExit(f'no mutant list tests/mutation/{name}.py (see --list)')
    spec = importlib.util.spec_from_file_location(f'mutants_{name}', path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod            # dataclasses need the module registered
    spec.loader.exec_module(mod)
    return list(mod.TESTS), list(mod.MUTANTS)


def lists():
    return sorted(p.stem for p in HERE.glob('*.py') if p.stem not in ('mutate', '__init__'))


def check_clean(path: pathlib.Path) -> None:
    rel = path.relative_to(ROOT)
    r = subprocess.run(['git', 'diff', '--quiet', 'HEAD', '--', str(rel)], cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f'refusing to mutate {rel}: it has uncommitted changes (commit or stash)')


def run_tests(tests, timeout: float) -> tuple:
    """pytest on the selection in a fresh bytecode cache; (passed, seconds, last output line)."""
    with tempfile.TemporaryDirectory(prefix='mutate-pyc-') as cache:
        env = dict(os.environ, PYTHONPYCACHEPREFIX=cache, PYTHONDONTWRITEBYTECODE='1')
        t0 = time.perf_counter()
        try:
            r = subprocess.run([sys.executable, '-m', 'pytest', '-x', '-q',
                                '-p', 'no:cacheprovider',
                                *tests], cwd=ROOT, env=env, capture_output=True, text=True,
                               timeout=timeout)
        except subprocess.TimeoutExpired:
            return False, time.perf_counter() - t0, f'timeout after {timeout:.0f} s'
        lines = [ln for ln in r.stdout.splitlines() if ln.strip()]
        return r.returncode == 0, time.perf_counter() - t0, lines[-1] if lines else ''


def apply_and_test(m: Mutant, tests, timeout: float) -> tuple:
    path = ROOT / m.file
    original = path.read_bytes()
    text = original.decode()
    count = text.count(m.old)
    if count != 1:
        return 'INVALID', 0.0, f'old text found {count} times in {m.file}'
    try:
        path.write_text(text.replace(m.old, m.new, 1))
        passed, secs, last = run_tests(tests, timeout)
    finally:
        path.write_bytes(original)
    if path.read_bytes() != original:      # pragma: no cover - write_bytes failed silently
        raise SystemExit(f'could not restore {m.file}: restore it from git before anything else')
    return ('SURVIVED' if passed else 'killed'), secs, last


def run_list(name: str, k: str, timeout: float):
    """Run one mutant list: [(Mutant, 'killed' | 'SURVIVED' | 'INVALID')], or None when the
    list selects nothing or its baseline fails."""
    tests, mutants = load_list(name)
    keys = [x for x in k.split(',')] if k else ['']
    mutants = [m for m in mutants if any(x in m.id for x in keys)]
    if not mutants:
        print(f'{name}: no mutants selected')
        return None
    for f in sorted({m.file for m in mutants}):
        check_clean(ROOT / f)
    ok, secs, last = run_tests(tests, timeout)
    print(f'baseline: pytest {" ".join(tests)}: {"passed" if ok else "FAILED"} in '
          f'{secs:.0f} s ({last})',
          flush=True)
    if not ok:
        return None
    results = []
    for m in mutants:
        res, secs, last = apply_and_test(m, list(m.tests) or tests, timeout)
        results.append((m, res))
        print(f'{m.id} {res:8s} {secs:5.0f} s  {m.file}: {m.why}' +
              (f'  [{last}]' if res != 'killed' else ''), flush=True)
    killed = sum(r == 'killed' for _, r in results)
    survived = [m for m, r in results if r == 'SURVIVED']
    invalid = [m for m, r in results if r == 'INVALID']
    unexplained = [m for m in survived if not m.harmless]
    print(f'{name}: {len(results)} mutants, {killed} killed, {len(survived)} survived '
          f'({len(survived) - len(unexplained)} known harmless, {len(unexplained)} not)'
          + (f', {len(invalid)} invalid (old text not found once)' if invalid else ''))
    for m in survived:
        print(f'  survivor {m.id}: {m.why}' +
              (f' -- harmless: {m.harmless}' if m.harmless else ' -- NOT EXPLAINED'))
    for m, r in results:
        if m.harmless and r == 'killed':
            print(f'  note: {m.id} is marked harmless but was killed: drop the mark')
    return results


def package_of(m: Mutant) -> str:
    parts = pathlib.PurePosixPath(m.file).parts
    return parts[1] if len(parts) > 2 and parts[0] == 'src' else parts[0]


def table(results) -> str:
    """Per package: mutants, killed, harmless survivors, meaningful survivors, invalid."""
    rows = {}
    for m, r in results:
        row = rows.setdefault(package_of(m), [0, 0, 0, 0, 0])
        row[0] += 1
        row[1] += r == 'killed'
        row[2] += r == 'SURVIVED' and bool(m.harmless)
        row[3] += r == 'SURVIVED' and not m.harmless
        row[4] += r == 'INVALID'
    total = [sum(col) for col in zip(*rows.values(), strict=True)] if rows else [0] * 5
    lines = ['| package | mutants | killed | survived, harmless | survived, meaningful | invalid |',
             '|---|---|---|---|---|---|']
    for pkg in sorted(rows):
        lines.append('| ' + pkg + ' | ' + ' | '.join(str(v) for v in rows[pkg]) + ' |')
    lines.append('| **total** | ' + ' | '.join(str(v) for v in total) + ' |')
    meaningful = total[0] - total[2]
    lines.append(f'meaningful survivors: {total[3]} of {meaningful} meaningful mutants '
                 f'({100.0 * total[3] / max(meaningful, 1):.0f} %)')
    return '\n'.join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('name', nargs='?', help="mutant list: tests/mutation/<name>.py, or 'all'")
    ap.add_argument('-k', default='', help='only mutants whose id contains this text (or one '
                                           'of several, comma-separated)')
    ap.add_argument('--timeout', type=float, default=600.0, help='seconds per pytest run')
    ap.add_argument('--list', action='store_true', help='print the mutant lists and exit')
    ap.add_argument('--check', action='store_true',
                    help='run nothing: check that each old text occurs exactly once (after edits)')
    a = ap.parse_args(argv)
    if a.list or not a.name:
        print('mutant lists: ' + ', '.join(lists()))
        return 0 if a.list else 2
    names = lists() if a.name == 'all' else [a.name]
    if a.check:
        bad = 0
        for name in names:
            for m in load_list(name)[1]:
                n = (ROOT / m.file).read_text().count(m.old)
                if n != 1:
                    bad += 1
                    print(f'{name} {m.id}: old text found {n} times in {m.file}')
        print(f'{bad} mutant(s) need their old text updated' if bad
              else 'every old text found once')
        return 1 if bad else 0
    results, status = [], 0
    for name in names:
        if len(names) > 1:
            print(f'== {name}', flush=True)
        res = run_list(name, a.k, a.timeout)
        if res is None:
            status = 2
            continue
        results += res
    if len(names) > 1 or results:
        print(table(results))
    if status:
        return status
    bad = [m for m, r in results if r == 'INVALID' or (r == 'SURVIVED' and not m.harmless)]
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
