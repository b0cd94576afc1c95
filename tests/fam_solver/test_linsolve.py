"""Newton-step linear algebra: the O(N) solves against the dense Jacobian, and the branch /
stability check against the eigenvalues it stands for."""
import numpy as np
import pytest

from fam_solver import equations, linsolve, problem


def _factors(n, follower, clothoid, seed, scale=2.0, point_forces=()):
    rng = np.random.default_rng(seed)
    prob = problem.make_problem(n, 1.0, 1.0, np.array([2.0 - 3.0j]), follower, np.array([0.7]),
                                list(point_forces), clothoid=clothoid)
    loads, m = prob.loads(1.0)
    phi = rng.normal(0, scale / n, (1, n))
    _, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m, clothoid=clothoid)
    return prob, fac, rng


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('clothoid', [False, True])
@pytest.mark.parametrize('n', [1, 2, 7, 65, 300])
def test_banded_and_structured_solves_equal_the_dense_one(follower, clothoid, n):
    prob, fac, rng = _factors(n, follower, clothoid, seed=n)
    J = linsolve.dense_jacobian(prob.w, fac)[0]
    b = rng.normal(size=n)
    x = linsolve.banded_solve(prob.w, tuple(f[0] for f in fac), b)
    assert np.abs(J @ x - b).max() < 1e-12 * max(1.0, np.abs(J).max() * np.abs(x).max())
    y = linsolve.structured_solve(prob.w, fac, b[None])[0]
    assert np.abs(J @ y - b).max() < 1e-10 * max(1.0, np.abs(J).max() * np.abs(y).max())


def test_banded_solve_with_point_forces_and_graded_arcs():
    n = 40
    rng = np.random.default_rng(7)
    frac = rng.uniform(0.5, 2.0, n)
    frac /= frac.sum()
    prob = problem.make_problem(n, 1.0, 1.0, np.array([1.0 + 2.0j]), False, np.array([0.3]),
                                [(0.37, np.array([-2.0 + 1.0j]))], fractions=frac)
    loads, m = prob.loads(1.0)
    phi = rng.normal(0, 0.05, (1, n))
    _, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m)
    J = linsolve.dense_jacobian(prob.w, fac)[0]
    b = rng.normal(size=n)
    x = linsolve.banded_solve(prob.w, tuple(f[0] for f in fac), b)
    assert np.allclose(J @ x, b, atol=1e-12)


def test_energy_hessian_is_symmetric_for_dead_loads_on_circular_arcs():
    """W^-1 J is the Hessian of the potential energy (why the Cholesky test is exact there)."""
    prob, fac, _ = _factors(9, False, False, seed=1, point_forces=[(0.4, np.array([1.0 + 1.0j]))])
    J = linsolve.dense_jacobian(prob.w, fac)[0]
    H = J / prob.w[:, None]
    assert np.abs(H - H.T).max() < 1e-12 * np.abs(H).max()


@pytest.mark.parametrize('follower', [False, True])
@pytest.mark.parametrize('clothoid', [False, True])
def test_energy_stable_agrees_with_the_eigenvalues(follower, clothoid):
    """Across loads from small to far past buckling (compressive, so that eigenvalues cross
    zero), the check says exactly what 'every eigenvalue has a real part > 1e-9' says."""
    n = 10
    rng = np.random.default_rng(11)
    seen = set()
    for _ in range(80):
        F = rng.uniform(0, 40) * np.exp(1j * rng.uniform(np.pi / 2, 3 * np.pi / 2))
        prob = problem.make_problem(n, 1.0, 1.0, np.array([F]), follower, np.array([0.0]), [],
                                    clothoid=clothoid)
        loads, m = prob.loads(1.0)
        phi = rng.normal(0, 0.3, (1, n)) * rng.choice([0.0, 1.0])
        _, fac, _ = equations.evaluate(phi, prob.l, prob.w, loads, m, clothoid=clothoid)
        J = linsolve.dense_jacobian(prob.w, fac)[0]
        expect = bool(np.linalg.eigvals(J).real.min() > 1e-9)
        assert linsolve.energy_stable(J, prob.w) == expect
        assert linsolve.principal_ok(prob.w, fac)[0] == expect
        seen.add(expect)
    # both outcomes exercised (a follower tip force never buckles by divergence: Beck's column)
    assert seen == ({True} if follower else {True, False})
