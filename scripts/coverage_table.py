"""Per-package line coverage from the combined coverage data of scripts/coverage.

Every module of src/<pkg>/<pkg>/ counts, also one no test imported (all of its lines missed).
Prints a markdown table (package, statements, missed, %, the least covered modules) and
exits 1 when a package is below --min percent.
"""
from __future__ import annotations

import argparse
import pathlib
import sys

import coverage

ROOT = pathlib.Path(__file__).resolve().parents[1]


def package_modules(pkg_dir: pathlib.Path):
    inner = pkg_dir / pkg_dir.name
    return sorted(p for p in inner.rglob('*.py')) if inner.is_dir() else []


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--min', type=float, default=90.0, help='threshold, percent')
    ap.add_argument('--worst', type=int, default=3, help='least covered modules listed')
    a = ap.parse_args(argv)
    cov = coverage.Coverage(config_file=str(ROOT / '.coveragerc'), data_suffix=False)
    cov.load()
    cov.combine(strict=False)       # children's data files pytest-cov left (if any)
    print('| package | statements | missed | line coverage | least covered modules |')
    print('|---|---|---|---|---|')
    low = []
    for pkg_dir in sorted(p for p in (ROOT / 'src').iterdir() if (p / 'package.xml').exists()):
        n = miss = 0
        per_file = []
        for f in package_modules(pkg_dir):
            _, stmts, _, missing, _ = cov.analysis2(str(f))
            n += len(stmts)
            miss += len(missing)
            if stmts:
                per_file.append((100.0 * (1 - len(missing) / len(stmts)), f.name))
        if n == 0:
            continue
        pct = 100.0 * (n - miss) / n
        worst = ', '.join(f'{name} {p:.0f} %' for p, name in sorted(per_file)[:a.worst])
        flag = '' if pct >= a.min else f' (< {a.min:g} %)'
        print(f'| {pkg_dir.name} | {n} | {miss} | {pct:.1f} %{flag} | {worst} |')
        if pct < a.min:
            low.append(pkg_dir.name)
    if low:
        print(f'below {a.min:g} %: {", ".join(low)}')
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
