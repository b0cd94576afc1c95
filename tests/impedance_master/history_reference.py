"""The history identifier's re-fit as it was before issue 15's rework (main at 8ac48fb): the
reference the reworked `HistoryIdentifier` is tested against (same models to ~1e-10) and
timed against (tests/bench/bench_ima.py).

Before: each moving sample wrote a dense P-wide row into a batch (`_Phi`); every
`solve_every` samples the batch was folded in with ``A = lam^k A + Phi.T @ Phi``; each
candidate's block was cut with np.ix_ and solved with scipy's cho_factor / cho_solve; a
selection solved every candidate in full (clamp rounds included) and the selected one was
solved again for the model; `_model` went through `Impedance.from_arrays`.

Only the changed methods are overridden; the rest (gate, despiker, friction states,
clipping, anchors, envelope) is the shared code, unchanged by the rework.
"""
from __future__ import annotations

import numpy as np
from scipy.linalg import cho_factor, cho_solve

from impedance_master.history import HistoryIdentifier
from impedance_master.impedance import Impedance


class BatchHistoryIdentifier(HistoryIdentifier):
    """`HistoryIdentifier` with the pre-issue-15 re-fit (see module doc)."""

    def reset(self) -> None:
        super().reset()
        self._A_mat = np.zeros((self.P, self.P))
        self._b = np.zeros(self.P)
        self._Phi = np.zeros((self.solve_every, self.P))
        self._f = np.zeros(self.solve_every)

    def information(self) -> np.ndarray:
        return self._A_mat.copy()

    def get_state(self) -> dict:
        state = super().get_state()          # flushes (this class's _flush)
        state['A'], state['b'] = self._A_mat.tolist(), self._b.tolist()
        return state

    def _install(self, arrays: dict):
        arrays = dict(arrays)
        self.reset()
        self._A_mat, self._b = arrays['A'], arrays['b'].copy()
        self.n_moving, self.selected = arrays['n_moving'], arrays['selected']
        self._last_k = self.selected
        if self.n_moving < self.window * self.rate:
            return None
        return self._solve(moved=True)

    def _add_row(self, x, xd, xdd, zs, f) -> None:
        G = self.n_nodes
        u = (x - self.x_min) / self.dx
        if u <= 0.0:
            j, w = 0, 0.0
        elif u >= G - 1:
            j, w = G - 2, 1.0
        else:
            j = int(u)
            w = u - j
        w0 = 1.0 - w
        row = self._Phi[self._rows]
        row[j] = w0
        row[j + 1] = w
        g = G
        for z1, z2 in zs:
            row[g + j] = w0 * z1
            row[g + j + 1] = w * z1
            g += G
            dz = z2 - z1
            row[g + j] = w0 * dz
            row[g + j + 1] = w * dz
            g += G
        vz = xd / self._V
        row[g + j] = w0 * vz
        row[g + j + 1] = w * vz
        row[-1] = xdd / self._A
        self._f[self._rows] = f
        self._rows += 1
        self.n_moving += 1

    def _flush(self) -> None:
        k = self._rows
        self._moving_in_batch = k
        if k == 0:
            return
        Phi = self._Phi[:k]
        decay = self._lam ** k
        self._A_mat *= decay
        self._b *= decay
        self._A_mat += Phi.T @ Phi
        self._b += Phi.T @ self._f[:k]
        self._Phi[:k] = 0.0
        self._rows = 0

    def _solve_candidate(self, k: int, bound=None):
        idx = self._cand[k]
        M = self._A_mat[np.ix_(idx, idx)]
        M += self._cand_prior[k]
        b = self._b[idx]
        lo, hi = self._cand_lo[k], self._cand_hi[k]
        free = np.ones(idx.size, dtype=bool)
        theta = _spd_solve(M, b)
        for _ in range(3):
            bad = free & ((theta < lo) | (theta > hi))
            if not bad.any():
                break
            theta[bad] = np.clip(theta[bad], lo[bad], hi[bad])
            free &= ~bad
            fi = np.flatnonzero(free)
            rhs = b[fi] - M[np.ix_(fi, np.flatnonzero(~free))] @ theta[~free]
            theta[fi] = _spd_solve(M[np.ix_(fi, fi)], rhs)
        theta = np.clip(theta, lo, hi)
        return theta, float(theta @ M @ theta - 2.0 * b @ theta)

    def _select(self) -> dict:
        if self._K == 1:
            return {}
        cur = self.selected
        objs = [self._solve_candidate(k)[1] for k in range(self._K)]
        best = int(np.argmin(objs))
        var = (1.25 * self.scale) ** 2
        if best != cur and objs[cur] - objs[best] > self.select_margin * var:
            self.selected = best
            self.n_selections += 1
        return {}            # nothing reused: the selected candidate is solved again

    def _model(self, theta: np.ndarray) -> Impedance:
        G = self.n_nodes
        S = theta[:G]
        C = theta[3 * G:4 * G] / self._V
        idx = self._cand[self.selected]
        info = np.diag(self._A_mat)[idx]
        k, off = _line(self._nodes, S, info[:G] + 1e-9)
        wc = info[3 * G:4 * G] + 1e-9
        c = float(np.sum(wc * C) / np.sum(wc))
        return Impedance.from_arrays(
            float(theta[-1]) / self._A, c, k, off, x0=self.x_min, dx=self.dx,
            sigma=self.sigmas[self.selected], v_s=self.v_s, beta=self.beta,
            S=S - (k * self._nodes + off), F=theta[G:2 * G], B=theta[2 * G:3 * G], C=C - c,
            status='ok')


def _spd_solve(M: np.ndarray, b: np.ndarray) -> np.ndarray:
    try:
        return cho_solve(cho_factor(M, check_finite=False), b, check_finite=False)
    except np.linalg.LinAlgError:
        return np.linalg.solve(M, b)


def _line(x: np.ndarray, y: np.ndarray, w: np.ndarray):
    sw = w.sum()
    mx = (w * x).sum() / sw
    my = (w * y).sum() / sw
    dx = x - mx
    sxx = (w * dx * dx).sum()
    k = (w * dx * (y - my)).sum() / sxx if sxx > 0.0 else 0.0
    return float(k), float(my - k * mx)
