"""Code that benchmarks run in child processes (a string, so no linter or import sees it) must
still import: bench_sim_slave's 'bare' reference probe imported QOS_FAST from a module it had
left, its process died at start, and the benchmark measured an empty stream (scripts/bench
exit 1)."""
import pathlib
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_bench_sim_slave_probe_imports_resolve():
    sys.path.insert(0, str(ROOT / 'tests' / 'bench'))
    try:
        import bench_sim_slave
    finally:
        sys.path.pop(0)
    paths = [str(p) for p in sorted((ROOT / 'src').iterdir()) if (p / 'package.xml').exists()]
    code = bench_sim_slave.PROBE.format(paths=paths)
    compile(code, 'PROBE', 'exec')
    imports = '\n'.join(line for line in code.splitlines()
                        if line.startswith(('import ', 'from ', 'sys.path')))
    exec(compile(imports, 'PROBE imports', 'exec'), {'sys': sys})
