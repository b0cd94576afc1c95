"""Ordered centreline of a segmented catheter: skeleton (without the parts where the mask is
thinner than a catheter) -> longest geodesic path on the
8-connected pixel graph (two Dijkstra passes, which ignores spurs) -> base/tip orientation
-> ends restored along their tangents (a skeleton stops about half a width short of each
end) -> light smoothing of the pixel staircase.

Pure numpy/scipy/scikit-image; no rclpy. Pixel coordinates are (u, v) = (column, row).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import cv2
import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from skimage.morphology import skeletonize

from catheter_shape.flatfield import _median

__all__ = ['Centerline', 'skeleton_path', 'extend_end', 'smooth_path']

#: skeleton pixels where the mask's half-width is below this fraction of the catheter's are
#: not the catheter
THIN = 0.7


@dataclass
class Centerline:
    """status 'ok' or a reason; pixels (N, 2) float (u, v) ordered base -> tip;
    base_cut True when the path was cut at base_px (the clamp was in the mask)."""
    status: str
    pixels: Optional[np.ndarray] = None
    base_cut: bool = False
    skeleton_px: int = 0
    message: str = ''


#: the 8 neighbour offsets (dy, dx) and their edge lengths
_NB = np.array([(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)])
_NB_W = np.hypot(_NB[:, 0], _NB[:, 1])


def _neighbours(skel: np.ndarray):
    """Neighbour table of the skeleton pixels: (n, 8) node indices (-1: none) and the
    pixels (n, 2) (u, v) float."""
    pts = cv2.findNonZero(skel.view(np.uint8) if skel.dtype == bool else skel)
    pts = np.empty((0, 2), np.int32) if pts is None else np.asarray(pts).reshape(-1, 2)
    xs, ys = pts[:, 0], pts[:, 1]                        # row-major, as np.nonzero
    n = ys.size
    h, w = skel.shape
    idx = np.full((h + 2, w + 2), -1, np.int32)          # padded: no bounds checks
    idx[ys + 1, xs + 1] = np.arange(n, dtype=np.int32)
    nb = idx[(ys + 1)[:, None] + _NB[:, 0], (xs + 1)[:, None] + _NB[:, 1]]
    return nb, np.stack([xs, ys], axis=1).astype(float)


def _csr(nb: np.ndarray, keep: Optional[np.ndarray] = None) -> csr_matrix:
    """The symmetric 8-connected pixel graph of a neighbour table (edge weights 1 and
    sqrt(2)), built directly in CSR form; keep (bool (n,)): the subgraph of those nodes,
    renumbered in order."""
    if keep is not None:
        new = np.cumsum(keep, dtype=np.int32) - 1
        nb = nb[keep]
        ok = nb >= 0
        ok[ok] = keep[nb[ok]]
        nb = np.where(ok, new[nb], -1)
    else:
        ok = nb >= 0
    n = nb.shape[0]
    indptr = np.zeros(n + 1, np.int32)
    np.cumsum(ok.sum(axis=1), out=indptr[1:])
    return csr_matrix((np.broadcast_to(_NB_W, nb.shape)[ok], nb[ok], indptr), shape=(n, n))


def _path(pred: np.ndarray, start: int, end: int) -> np.ndarray:
    pl = pred.tolist()
    out = [end]
    k = end
    while k != start and k >= 0:
        k = pl[k]
        out.append(k)
    return np.array(out[::-1], dtype=np.int64)


def skeleton_path(mask: np.ndarray, offset: Tuple[int, int], base_px=None,
                  image_shape: Optional[Tuple[int, int]] = None,
                  min_length_px: float = 10.0, width_px: Optional[float] = None) -> Centerline:
    """Longest geodesic path of the skeleton of `mask` (uint8/bool ROI at `offset` (u0, v0)),
    in full-frame pixels, ordered base -> tip.

    base_px: (u, v) of the clamp. Given: the tip is the skeleton end farthest (along the
    skeleton) from the pixel nearest base_px, the base the end farthest from that tip; if
    base_px lies inside the image and the path passes it well before its end (the clamp is
    part of the mask), the path is cut at the pixel nearest base_px. Not given: the base is
    the path end nearest the image border (image_shape (H, W) needed).

    width_px: the catheter's width; given, runs of skeleton pixels at least a width long
    where the mask is thinner than `THIN` of a catheter's (its mask is about 0.9 width_px
    wide) are dropped first: a thin structure touching the catheter (a wire across it, a
    guidewire out of its tip) cannot carry the path away from it; a short dip of a noisy
    mask stays."""
    skel = skeletonize(mask.astype(bool))
    n = int(np.count_nonzero(skel))
    if n < 2:
        return Centerline('bad_skeleton', skeleton_px=n, message=f'skeleton has {n} pixel(s)')
    nbt, xy = _neighbours(skel)
    keep = None
    if width_px is not None:
        # only runs of thin skeleton at least a width long: a short dip of a noisy mask
        # stays, a wire goes (runs: connected components of the thin nodes' subgraph)
        m = cv2.copyMakeBorder(mask.astype(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
        dt = cv2.distanceTransform(m, cv2.DIST_L2, 3)
        ij = xy.astype(int) + 1
        thin = dt[ij[:, 1], ij[:, 0]] < THIN * 0.45 * width_px
        if np.count_nonzero(thin) >= width_px:          # else no run can be a width long
            _, lab = connected_components(_csr(nbt, thin), directed=False)
            drop = np.zeros(n, bool)
            drop[thin] = np.bincount(lab)[lab] >= width_px
            if drop.any():
                keep = ~drop
                if np.count_nonzero(keep) < 2:
                    return Centerline('bad_skeleton', skeleton_px=int(np.count_nonzero(keep)),
                                      message='no part of the object is as wide as a catheter')
                xy = xy[keep]
    g = _csr(nbt, keep)
    off = np.asarray(offset, dtype=float)
    xy += off
    if base_px is not None:
        b = np.asarray(base_px, dtype=float)
        s0 = int(np.argmin(np.sum((xy - b) ** 2, axis=1)))
    else:
        s0 = 0
    d1 = dijkstra(g, indices=s0)
    d1[~np.isfinite(d1)] = -1.0                              # other skeleton pieces: ignore
    a = int(np.argmax(d1))
    d2, pred = dijkstra(g, indices=a, return_predecessors=True)
    d2[~np.isfinite(d2)] = -1.0
    bnd = int(np.argmax(d2))
    length = float(d2[bnd])
    if length < min_length_px:
        return Centerline('too_short', skeleton_px=n,
                          message=f'longest skeleton path {length:.1f} px < {min_length_px:.1f}')
    path = _path(pred, a, bnd)                                 # a -> bnd
    px = xy[path]
    base_cut = False
    if base_px is not None:
        # a was found as the farthest from the base: it is the tip; orient base -> tip
        px = px[::-1]
        H, W = image_shape if image_shape is not None else (np.inf, np.inf)
        if 0 <= b[0] <= W - 1 and 0 <= b[1] <= H - 1:
            k = int(np.argmin(np.sum((px - b) ** 2, axis=1)))
            seg = np.sqrt(np.sum(np.diff(px[:k + 1], axis=0) ** 2, axis=1)).sum() if k else 0.0
            dist_b = float(np.sqrt(np.sum((px[k] - b) ** 2)))
            # the mask runs past the base (clamp): cut there
            if k > 0 and seg > dist_b + 3.0:
                px = px[k:]
                base_cut = True
    elif image_shape is not None:
        H, W = image_shape

        def border(p):
            return min(p[0], p[1], W - 1 - p[0], H - 1 - p[1])
        if border(px[-1]) < border(px[0]):
            px = px[::-1]
    if px.shape[0] < 2:
        return Centerline('too_short', skeleton_px=n, message='path has fewer than 2 pixels')
    return Centerline('ok', pixels=px, base_cut=base_cut, skeleton_px=n)


def _bilinear(img: np.ndarray, pts: np.ndarray) -> np.ndarray:
    H, W = img.shape
    x = np.clip(pts[:, 0], 0, W - 1.000001)
    y = np.clip(pts[:, 1], 0, H - 1.000001)
    x0 = x.astype(np.int64)
    y0 = y.astype(np.int64)
    fx = x - x0
    fy = y - y0
    # the four neighbours in one gather (a lazily evaluated darkness computes per call)
    n = x0.size
    v = img[np.concatenate([y0, y0, y0 + 1, y0 + 1]), np.concatenate([x0, x0 + 1, x0, x0 + 1])]
    return ((v[:n] * (1 - fx) + v[n:2 * n] * fx) * (1 - fy)
            + (v[2 * n:3 * n] * (1 - fx) + v[3 * n:] * fx) * fy)


def extend_end(px: np.ndarray, score: np.ndarray, level: float, width_px: float,
               trim_px: float, at_start: bool = False,
               half_contrast: bool = True, quadratic: bool = True,
               span_widths: float = 1.5) -> Tuple[np.ndarray, float, bool]:
    """Restore one end of an ordered path (N, 2): drop the last trim_px of it (a skeleton
    curls into a corner of a flat end), fit a parabola to the preceding ~1.5 widths (the
    end may bend strongly: a loaded catheter's base) and walk along it until the darkness
    `score` falls below the edge level (bilinear, sub-pixel crossing) or the image border,
    at most 1.5 widths + trim beyond the cut.

    The edge level is `level` (the segmentation threshold), or with half_contrast the
    midpoint between the catheter's darkness on the path and the local background beside
    it (an unbiased edge for a symmetric blur; a threshold above the midpoint would put
    the end inside the tube). Returns (new path, extension length px, found): found is
    False when the darkness never fell to the edge level within the search (the path is
    then extended by the whole search length and should not be trusted)."""
    if at_start:
        p, ext, found = extend_end(px[::-1], score, level, width_px, trim_px, False,
                                   half_contrast, quadratic, span_widths)
        return p[::-1], ext, found
    if not np.isfinite(level):
        raise ValueError(f'level must be finite, got {level!r}')
    H, W = score.shape
    seg = np.sqrt(np.sum(np.diff(px, axis=0) ** 2, axis=1))
    s = np.concatenate([[0.0], np.cumsum(seg)])
    L = s[-1]
    if L < 3 * max(trim_px, 1.0) + 4:
        return px, 0.0, True
    keep = s <= L - trim_px
    body = px[keep]
    sb = s[keep]
    span = max(span_widths * width_px, 6.0)
    tail = body[sb >= sb[-1] - span]
    if tail.shape[0] < 3:
        return px, 0.0, True
    c = tail.mean(axis=0)
    _, _, vt = np.linalg.svd(tail - c, full_matrices=False)
    d = vt[0]
    if np.dot(d, tail[-1] - tail[0]) < 0:
        d = -d
    nrm = np.array([-d[1], d[0]])
    a = (tail - c) @ d
    bq = (tail - c) @ nrm
    if quadratic and tail.shape[0] >= 5 and np.ptp(a) > 2.0:
        coef = np.polyfit(a, bq, 2)
        # bound the curvature: a bending radius of at least 3 widths (the Blazer under 0.3 N
        # bends to 7 mm = 3 widths at most; a skeleton's corner curl bends tighter)
        coef[0] = np.clip(coef[0], -1.0 / (6.0 * width_px), 1.0 / (6.0 * width_px))
    else:
        coef = np.array([0.0, 0.0, 0.0])
    a_e = float(np.dot(body[-1] - c, d))
    max_t = trim_px + 1.5 * width_px + 2.0
    aa = a_e + np.arange(0.0, max_t, 0.25)

    def curve(x):
        return c + x[:, None] * d + np.polyval(coef, x)[:, None] * nrm
    pts = curve(aa)
    inside_img = (pts[:, 0] >= 0) & (pts[:, 0] <= W - 1) & (pts[:, 1] >= 0) & (pts[:, 1] <= H - 1)
    vals = _bilinear(score, pts)
    lvl = level
    if half_contrast:
        core = _median(_bilinear(score, tail))
        tg = np.polyval(np.polyder(coef), a_e)
        n_e = nrm - tg * d
        n_e /= np.linalg.norm(n_e)
        side = np.vstack([pts[0] + 1.5 * width_px * n_e, pts[0] - 1.5 * width_px * n_e])
        ok = (side[:, 0] >= 0) & (side[:, 0] <= W - 1) & (side[:, 1] >= 0) & (side[:, 1] <= H - 1)
        if ok.any() and core > level:
            bg = float(np.min(_bilinear(score, side[ok])))
            mid = 0.5 * (core + bg)
            if bg < level < core:
                lvl = mid
    below = (vals <= lvl) | ~inside_img
    j = int(np.argmax(below)) if below.any() else aa.size - 1
    if j == 0:
        t_end = aa[0]
    elif not inside_img[j]:
        t_end = aa[j - 1]
    else:
        v0, v1 = vals[j - 1], vals[j]
        f = (v0 - lvl) / (v0 - v1) if v0 != v1 else 0.0
        t_end = aa[j - 1] + f * (aa[j] - aa[j - 1])
    ext = float(t_end - a_e)
    # new points every pixel (along the axis) up to the sub-pixel end
    steps = np.append(np.arange(a_e, t_end - 0.1, 1.0), t_end)
    new = curve(steps)
    return np.vstack([body[:-1], new]), ext, bool(below.any())


def smooth_path(px: np.ndarray, window: int = 5) -> np.ndarray:
    """Moving average along the path (odd window), ends kept, to remove the pixel staircase."""
    if window < 3 or px.shape[0] < window + 2:
        return px
    k = window // 2
    c = np.cumsum(np.vstack([np.zeros((1, 2)), px]), axis=0)
    out = px.copy()
    out[k:-k] = (c[2 * k + 1:] - c[:-2 * k - 1]) / (2 * k + 1)
    # taper the window towards the ends
    for i in range(1, k):
        out[i] = px[:2 * i + 1].mean(axis=0)
        out[-1 - i] = px[-2 * i - 1:].mean(axis=0)
    return out
