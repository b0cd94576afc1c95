"""ShapeSensor: camera frame -> mask -> ordered centreline -> plausibility checks -> Bezier
control points (thesis section 2.2.2, Eqs. 1-5). Pure numpy/OpenCV/scikit-image; no rclpy.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Dict, Optional

import numpy as np

from catheter_common.checks import finite, nonneg, positive
from catheter_shape.bezier import _dist, _newton_params, _project_global, fit_bezier_detailed
from catheter_shape.camera import BLAZER_DIAMETER, _check_psi
from catheter_shape.centerline import extend_end, skeleton_path, smooth_path
from catheter_shape.flatfield import flat_field, local_half_peak, prepare_background
from catheter_shape.plausibility import (MAX_KINK, MAX_TURNING, check_fold, inside_frame,
                                         on_border, path_length)
from catheter_shape.segmentation import (FULL_SCALE, METHODS, catheter_component,
                                         threshold_frame, to_gray, to_uint8)

__all__ = ['Observation', 'ShapeSensor', 'STATUSES', 'CHECK_STATUSES']

#: how much of the skeleton is dropped at the base before its end is restored (widths)
BASE_TRIM = 0.5
#: ... and of a path cut at the clamp (the clamp in the mask), from the cut (widths)
BASE_TRIM_CUT = 1.0

#: statuses after which a flat-field frame is measured again with each pixel held to half of
#: its neighbourhood's darkness (something darker than the catheter merged with it)
RETRY_STATUSES = ('bad_segmentation', 'length_mismatch', 'folded', 'bad_tip', 'base_mismatch')

#: the statuses of the plausibility checks (a frame that fails one is never ok)
CHECK_STATUSES = ('outside_frame', 'tip_out_of_view', 'bad_tip', 'base_mismatch',
                  'ambiguous_base', 'length_mismatch', 'folded', 'poor_fit')
#: every status an Observation can carry
STATUSES = ('ok', 'bad_input', 'low_contrast', 'no_catheter', 'bad_segmentation',
            'multiple_objects', 'bad_skeleton', 'too_short', 'fit_failed') + CHECK_STATUSES


@dataclass
class Observation:
    """What the sensor saw in one frame.

    ok: True when control points are valid. status: one of STATUSES; message: details.
    points: (N, 3) m, catheter_base, ordered base -> tip ((0, 3) when not ok).
    control_points: (degree + 1, 3) m, p0 at the base, p_n at the tip (NaN when not ok).
    residual: mean perpendicular distance of the points to the curve, m (NaN when not ok).
    max_distance: largest perpendicular distance, m.
    length: arc length of the measured centreline, m (NaN before it is known).
    pixels: (N, 2) the ordered centreline in pixels (u, v).
    tip_px, base_px: (2,) pixel of the tip and base ends found.
    contrast: the catheter's relative darkness (flatfield method; NaN otherwise).
    timings: seconds per stage ('gray', 'threshold', 'component', 'skeleton', 'ends',
    'fit', 'total').
    area_px: catheter pixels; bridged: gaps joined; base_cut: path cut at the clamp.
    """
    ok: bool
    status: str
    message: str = ''
    points: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    control_points: np.ndarray = field(default_factory=lambda: np.full((4, 3), np.nan))
    residual: float = float('nan')
    max_distance: float = float('nan')
    length: float = float('nan')
    pixels: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    tip_px: Optional[np.ndarray] = None
    base_px: Optional[np.ndarray] = None
    contrast: float = float('nan')
    timings: Dict[str, float] = field(default_factory=dict)
    area_px: int = 0
    bridged: int = 0
    base_cut: bool = False
    roi: Optional[tuple] = None
    mask: Optional[np.ndarray] = None


class ShapeSensor:
    """Camera frame -> Bezier control points of the catheter centreline.

    psi: (3, 4) calibration matrix (Eq. 1), pixels -> metres in catheter_base (or 12 numbers
        row-major); `catheter_shape.make_psi(mm_per_px, base_px, angle)` builds it for a
        camera that looks straight at the bending plane.
    threshold: grey level (1-255) of method 'fixed' (the thesis's 132); other methods
        ignore it.
    background: optional uint8/uint16 (H, W) (or BGR) frame of the scene without the
        catheter (any exposure).
    base_px: optional (u, v) pixel of the clamp (the catheter_base origin). Given: the
        centreline must start there (or, for a clamp outside the image, enter from the
        border). Not given: the base is the end on the image border; a catheter with
        neither end on the border is refused ('ambiguous_base').
    method: 'flatfield' (default: illumination-independent, see catheter_shape.flatfield),
        'fixed' (the thesis), 'otsu' or 'adaptive' (see segmentation.threshold_frame).
    length: optional catheter length (clamp to tip), m. Given: a centreline longer than
        length * (1 + length_tolerance), or (base in view) shorter than min_visible *
        length, is refused ('length_mismatch').
    length_tolerance: relative, default 0.025 (1.6 mm on 65 mm; the measured length is
        within +-0.4 mm on the tuning styles). min_visible: fraction of the length that must
        be seen (tissue may hide the tip), default 0.5.
    base_tolerance: the centreline's base end may lie this many catheter widths from
        base_px (default 2.0; the skeleton stops half a width short); a centreline that runs
        past base_px (through a clamp in the mask) must pass within one width of it.
    max_turning, max_kink: rad, plausibility bounds of the centreline's tangent (total
        turning; turning within one catheter width); see catheter_shape.plausibility.
    max_fit_error: m, largest distance of a centreline point to the fitted curve (default
        3 mm; beyond: 'poor_fit').
    degree: Bezier degree (3 = the thesis's 4 control points).
    refine, correction, param_weight: parameter correction of the Bezier fit (see
        bezier.fit_bezier_detailed); refine=0 or correction='none' is the thesis's
        chord-length fit; the default 'regularized' keeps the control points stable (one
        round: on the style benchmark's frames a second changed nothing, and three cost
        0.5 ms more per frame for a slightly larger Bezier deviation).
    base_constraint: 'none', 'point' (p0 fixed at base_px) or 'tangent' (p0 fixed and the
        base tangent along +x of catheter_base, the clamp's direction); needs base_px.
    diameter: catheter diameter, m (sets size limits). max_gap: largest gap joined, m.
    min_length: shortest catheter accepted, m. smooth: moving-average window (pixels) on
        the ordered path (0 or 1 = off). max_fit_points: points used by the fit (evenly
        subsampled; the residual uses all points).
    """

    def __init__(self, psi, threshold: int = 132, background: Optional[np.ndarray] = None,
                 base_px=None, method: str = 'flatfield', degree: int = 3, refine: int = 1,
                 correction: str = 'regularized', param_weight: float = 0.05,
                 base_constraint: str = 'none', diameter: float = BLAZER_DIAMETER,
                 max_gap: float = 0.003, min_length: float = 0.005, smooth: int = 5,
                 max_fit_points: int = 60, keep_mask: bool = False,
                 length: Optional[float] = None, length_tolerance: float = 0.025,
                 min_visible: float = 0.5, base_tolerance: float = 2.0,
                 max_turning: float = MAX_TURNING, max_kink: float = MAX_KINK,
                 max_fit_error: float = 3e-3):
        self.psi = _check_psi(psi)
        if isinstance(threshold, bool) or not isinstance(threshold, (int, np.integer, float)) \
                or not np.isfinite(threshold) or not (1 <= threshold <= 255):
            raise ValueError(f'threshold must be a number in [1, 255], got {threshold!r}')
        self.threshold = int(round(threshold))
        if method not in METHODS:
            raise ValueError(f'method must be one of {METHODS}, got {method!r}')
        self.method = method
        if isinstance(degree, bool) or int(degree) != degree or not (1 <= degree <= 10):
            raise ValueError(f'degree must be an integer in [1, 10], got {degree!r}')
        self.degree = int(degree)
        if isinstance(refine, bool) or int(refine) != refine or refine < 0:
            raise ValueError(f'refine must be a non-negative integer, got {refine!r}')
        self.refine = int(refine)
        from catheter_shape.bezier import CORRECTIONS
        if correction not in CORRECTIONS:
            raise ValueError(f'correction must be one of {CORRECTIONS}, got {correction!r}')
        self.correction = correction
        self.param_weight = nonneg('param_weight', param_weight)
        self.diameter = positive('diameter', diameter)
        self.max_gap = nonneg('max_gap', max_gap)
        self.min_length = nonneg('min_length', min_length)
        if base_constraint not in ('none', 'point', 'tangent'):
            raise ValueError(f"base_constraint must be 'none', 'point' or 'tangent', "
                             f'got {base_constraint!r}')
        if base_px is not None:
            b = np.asarray(base_px, dtype=float).reshape(-1)
            if b.shape != (2,) or not np.all(np.isfinite(b)):
                raise ValueError(f'base_px must be (u, v) pixels, got {base_px!r}')
            base_px = b
        if base_constraint != 'none' and base_px is None:
            raise ValueError('base_constraint needs base_px')
        self.base_px = base_px
        self.base_constraint = base_constraint
        self.length = None if length is None else positive('length', length)
        self.length_tolerance = nonneg('length_tolerance', length_tolerance)
        self.min_visible = finite('min_visible', min_visible)
        if not 0.0 <= self.min_visible <= 1.0:
            raise ValueError(f'min_visible must be in [0, 1], got {min_visible!r}')
        self.base_tolerance = positive('base_tolerance', base_tolerance)
        self.max_turning = positive('max_turning', max_turning)
        self.max_kink = positive('max_kink', max_kink)
        self.max_fit_error = positive('max_fit_error', max_fit_error)
        if isinstance(smooth, bool) or int(smooth) != smooth or smooth < 0:
            raise ValueError(f'smooth must be a non-negative integer, got {smooth!r}')
        self.smooth = int(smooth)
        self.max_fit_points = max(int(max_fit_points), self.degree + 2)
        self.keep_mask = bool(keep_mask)
        # metres per pixel (the similarity part of psi) and an orthonormal basis of its plane
        A = self.psi[:, :2]
        self._m_per_px = float(np.sqrt(abs(np.linalg.det(A.T @ A)) ** 0.5))
        q, _ = np.linalg.qr(A)
        self._plane = q                                       # (3, 2)
        # image direction (unit, pixels) of +x of catheter_base: the clamped base tangent
        ex = np.linalg.lstsq(A, np.array([1.0, 0.0, 0.0]), rcond=None)[0]
        self._ex_px = ex / np.linalg.norm(ex)
        self._origin = self.psi[:, 3]
        self.background = None
        self._bg_f = None
        self._bg_max = None
        if background is not None:
            self.set_background(background)

    def set_background(self, background: Optional[np.ndarray]) -> None:
        """Set (or clear with None) the background frame (uint8/uint16 grey or BGR)."""
        if background is None:
            self.background = None
            self._bg_f = None
            self._bg_max = None
            return
        if not isinstance(background, np.ndarray):
            raise ValueError(f'background must be a numpy array, got {type(background).__name__}')
        self.background = to_gray(background).copy()
        self._bg_f = prepare_background(self.background, self.width_px)
        self._bg_max = float(self._bg_f.max())

    @property
    def width_px(self) -> float:
        """Catheter diameter in pixels."""
        return self.diameter / self._m_per_px

    def to_metres(self, uv: np.ndarray) -> np.ndarray:
        """Eq. 1 for pixels (N, 2) -> (N, 3) m."""
        return uv @ self.psi[:, :2].T + self._origin

    # --- the pipeline -------------------------------------------------------------------
    def process(self, frame: np.ndarray) -> Observation:
        """Measure the catheter in one frame: uint8 or uint16 (H, W) grey, (H, W, 3) BGR or
        (H, W, 4) BGRA. Returns an Observation (ok False with a status for a bad frame or an
        implausible shape); raises ValueError only if `frame` is not a numpy array."""
        if not isinstance(frame, np.ndarray):
            raise ValueError(f'frame must be a numpy array, got {type(frame).__name__}'
                             + (' (pass frame.image)' if hasattr(frame, 'image') else ''))
        t0 = time.perf_counter()
        tm: Dict[str, float] = {}
        fail = self._fail
        try:
            gray = to_gray(frame)
        except ValueError as exc:
            return fail('bad_input', str(exc), tm, t0)
        if gray.ndim != 2 or min(gray.shape) < 8:
            return fail('bad_input', f'frame too small: {gray.shape}', tm, t0)
        bg = self.background
        if bg is not None and bg.shape != gray.shape:
            return fail('bad_input', f'frame {gray.shape} does not match the background '
                                     f'{bg.shape}', tm, t0)
        t1 = time.perf_counter()
        tm['gray'] = t1 - t0
        full = FULL_SCALE[gray.dtype]
        lo, hi = float(gray.min()), float(gray.max())
        if hi - lo < 16 * full / 255.0:
            return fail('low_contrast', f'grey range {lo:.0f}..{hi:.0f}', tm, t0)
        w_px = self.width_px
        contrast = float('nan')
        if self.method == 'flatfield':
            ff = flat_field(gray, self._bg_f, w_px, full_scale=full, base_px=self.base_px,
                            base_dir=self._ex_px, background_max=self._bg_max)
            if ff.status != 'ok':
                return fail(ff.status, 'nothing darker than the noise', tm, t0)
            mask, score, level, contrast = ff.mask, ff.score, ff.level, ff.contrast
        else:
            mask, score, level = threshold_frame(to_uint8(gray), self.threshold,
                                                 None if bg is None else to_uint8(bg),
                                                 self.method, block=int(4 * w_px) | 1)
            if not np.isfinite(level):
                score, level = mask, 127.5          # 'adaptive': search the edge on the mask
        t2 = time.perf_counter()
        tm['threshold'] = t2 - t1
        obs = self._measure(mask, score, level, contrast, gray.shape, tm, t0, t2)
        if obs.status in RETRY_STATUSES and self.method == 'flatfield':
            # something darker than the catheter touches or crosses it (a lead wire that
            # moved since the background frame): at the catheter's half contrast a dark
            # thin line segments nearly as wide as the catheter. Again with each pixel
            # held to half of its own neighbourhood's darkness (its own half-maximum width)
            mask2 = local_half_peak(mask, score, w_px)
            if mask2 is not None:
                second = self._measure(mask2, score, level, contrast, gray.shape, dict(tm),
                                       t0, time.perf_counter())
                if second.ok:
                    return second
        return obs

    def _measure(self, mask, score, level, contrast, shape, tm, t0, t2) -> Observation:
        """Everything after the threshold: component, skeleton, ends, checks, fit."""
        fail = self._fail
        w_px = self.width_px
        min_area = max(8.0, 0.5 * self.min_length / self._m_per_px * w_px)
        seg = catheter_component(mask, min_area=min_area, max_gap_px=self.max_gap / self._m_per_px,
                                 width_px=w_px, base_px=self.base_px,
                                 apart_ok=self.length is not None)
        t3 = time.perf_counter()
        tm['component'] = t3 - t2
        if seg.status != 'ok':
            return fail(seg.status, seg.message, tm, t0)
        cl = skeleton_path(seg.mask, seg.offset, self.base_px, shape,
                           min_length_px=max(3.0, 0.5 * self.min_length / self._m_per_px),
                           width_px=w_px)
        t4 = time.perf_counter()
        tm['skeleton'] = t4 - t3
        if cl.status != 'ok':
            return fail(cl.status, cl.message, tm, t0)
        width = seg.area / max(path_length(cl.pixels), 1.0)
        if width > 2.5 * w_px or width < 0.3 * w_px:
            return fail('bad_segmentation', f'the dark object is {width:.1f} px wide for a '
                                            f'{w_px:.1f} px catheter', tm, t0)
        half_contrast = self.method == 'flatfield' or (self.background is not None
                                                        and self.method == 'fixed')
        px, status, message = self._ends(cl, score, level, shape, half_contrast)
        if status != 'ok':
            return fail(status, message, tm, t0)
        if self.smooth >= 3:
            px = smooth_path(px, self.smooth | 1)
        t5 = time.perf_counter()
        tm['ends'] = t5 - t4
        status, message, length = self._check_shape(px, shape)
        if status != 'ok':
            return fail(status, message, tm, t0, length=length)
        if seg.apart and length < self.length * (1.0 - self.length_tolerance):
            # another dark object was left out because it does not touch the clamp: that is
            # only safe when the object at the clamp is the whole catheter
            return fail('multiple_objects', f'a second dark object apart from the one at the '
                        f'clamp, which is {1e3 * length:.1f} mm long: not the whole '
                        f'{1e3 * self.length:.1f} mm catheter', tm, t0, length=length)
        return self._fit(px, seg, cl, tm, t0, t5, length, contrast)

    def _ends(self, cl, score, level, shape, half_contrast):
        """Restore the ends the skeleton lost and check the base and tip ends.
        Returns (pixels, status, message)."""
        px = cl.pixels
        w_px = self.width_px
        H, W = shape
        bp = self.base_px
        # The tip of a tip-loaded catheter carries no moment: nearly straight, extrapolate
        # along a line to the half-contrast edge (at most 1.5 widths beyond the skeleton).
        px, _, found = extend_end(px, score, level, w_px, trim_px=0.5 * w_px,
                                  half_contrast=half_contrast, quadratic=False, span_widths=2.0)
        if not found:
            return px, 'bad_tip', 'the darkness does not end within 1.5 widths of the skeleton'
        if on_border(px[-1], shape, 0.5 * w_px + 1.0):
            return px, 'tip_out_of_view', 'the tip end lies on the image border'
        bp_in = bp is not None and 0 <= bp[0] <= W - 1 and 0 <= bp[1] <= H - 1
        if not bp_in:
            # the catheter must enter from the border: restore the base end up to it (the
            # skeleton stops short of it and curls into a corner of the cut: a whole width
            # is dropped); the clamped base carries the largest moment, so a parabola
            # follows its curvature
            px, _, _ = extend_end(px, score, level, w_px, trim_px=w_px, at_start=True,
                                  half_contrast=half_contrast, quadratic=True, span_widths=3.0)
            if on_border(px[0], shape):
                return px, 'ok', ''
            if bp is None:
                return px, 'ambiguous_base', ('neither end of the catheter is on the image '
                                              'border: give base_px (the clamp pixel)')
            return px, 'base_mismatch', ('the clamp (base_px) is outside the image but the '
                                         'catheter does not enter from the border')
        b0 = px[0]
        gap = float(np.hypot(*(b0 - bp)))
        trim = BASE_TRIM * w_px
        if cl.base_cut:
            # the path ran through the clamp and was cut at its pixel nearest base_px. The
            # catheter's axis passes through the clamp point: a path that only passes near
            # it (one width or more) runs beside it, and cutting there would drop a piece
            # of the catheter. Nearer, the skeleton there is the axis of the clamp and
            # catheter together (a sheath wider than the catheter pulls it aside): drop
            # the part within BASE_TRIM_CUT widths and join the clamp point as below.
            if gap > min(1.0, self.base_tolerance) * w_px:
                return px, 'base_mismatch', (f'the catheter passes {gap:.1f} px from the clamp '
                                             f'pixel base_px (> 1 width)')
            trim = BASE_TRIM_CUT * w_px
        elif gap > self.base_tolerance * w_px:
            return px, 'base_mismatch', (f'the catheter starts {gap:.1f} px from the clamp '
                                         f'pixel base_px (> {self.base_tolerance:g} widths)')
        # the clamp point is calibrated and the clamped catheter leaves it along +x of
        # catheter_base: join it to the skeleton (which stops about half a width short,
        # and curls there) by a quadratic tangent to +x at the clamp
        sk = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(px, axis=0).T))])
        px = px[sk >= min(trim, 0.5 * sk[-1])]
        q2 = px[0]
        gap = float(np.hypot(*(q2 - bp)))
        q1 = bp + 0.5 * gap * self._ex_px
        k = np.arange(0.0, gap - 0.5)[:, None] / max(gap, 1e-9)
        joint = (1 - k) ** 2 * bp + 2 * k * (1 - k) * q1 + k ** 2 * q2
        return np.vstack([joint, px]), 'ok', ''

    def _check_shape(self, px, shape):
        """Plausibility of the ordered centreline (pixels). Returns (status, message,
        length m)."""
        length = path_length(px) * self._m_per_px
        if not inside_frame(px, shape):
            return 'outside_frame', 'a centreline point lies outside the frame', length
        # beyond where it enters the image, a tube whose centreline comes within half a width
        # of the border is cut by it: its visible part is not centred on the centreline
        H, W = shape
        edge = np.minimum(np.minimum(px[:, 0], W - 1 - px[:, 0]),
                          np.minimum(px[:, 1], H - 1 - px[:, 1]))
        s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(px, axis=0).T))])
        w_px = self.width_px
        if np.any((edge < 0.5 * w_px) & (s > 1.5 * w_px)):
            return ('outside_frame', 'the catheter runs along the image border (partly out of '
                    'view)', length)
        if self.length is not None:
            L = self.length
            if length > L * (1.0 + self.length_tolerance):
                return ('length_mismatch', f'the centreline is {1e3 * length:.1f} mm long for a '
                        f'{1e3 * L:.1f} mm catheter', length)
            bp = self.base_px
            H, W = shape
            base_in = bp is not None and 0 <= bp[0] <= W - 1 and 0 <= bp[1] <= H - 1
            if base_in and length < self.min_visible * L:
                return ('length_mismatch', f'only {1e3 * length:.1f} mm of a {1e3 * L:.1f} mm '
                        f'catheter is seen (< {self.min_visible:.0%})', length)
        why = check_fold(px, self.width_px, self.max_turning, self.max_kink)
        if why is not None:
            return 'folded', why, length
        return 'ok', '', length

    def _fit(self, px, seg, cl, tm, t0, t5, length, contrast) -> Observation:
        pts3 = self.to_metres(px)
        if pts3.shape[0] < self.degree + 2:
            return self._fail('too_short', f'{pts3.shape[0]} centreline points', tm, t0)
        # fit in orthonormal coordinates of the image plane (exact for any psi), on an
        # evenly subsampled set of points; the residual uses all points
        p2 = (pts3 - self._origin) @ self._plane
        n = p2.shape[0]
        sel = np.unique(np.linspace(0, n - 1, min(n, self.max_fit_points)).round().astype(int))
        start = tangent = None
        if self.base_constraint != 'none':
            start = (self.to_metres(self.base_px[None, :])[0] - self._origin) @ self._plane
            if self.base_constraint == 'tangent':
                tangent = np.array([1.0, 0.0, 0.0]) @ self._plane
        try:
            fit = fit_bezier_detailed(p2[sel], self.degree, refine=self.refine, start=start,
                                      start_tangent=tangent, correction=self.correction,
                                      param_weight=self.param_weight, global_residual=False,
                                      project=False)
        except (ValueError, np.linalg.LinAlgError) as exc:
            return self._fail('fit_failed', str(exc), tm, t0)
        ctrl2 = fit.control_points
        if not np.all(np.isfinite(ctrl2)):
            return self._fail('fit_failed', 'non-finite control points', tm, t0)
        s_all = np.interp(np.arange(n), sel, fit.params)
        # two Newton steps from the fit's own parameters (a third changed the residual by
        # < 1e-9 of itself on the style benchmark's frames)
        s_loc = _newton_params(ctrl2, p2, s_all, 2)
        d = _dist(ctrl2, p2, s_loc)
        # a local foot point can be a wrong local minimum only far from the curve, and its
        # distance is then too large, never too small: when the check would refuse the
        # frame, search those points globally (points within half a pixel cannot change
        # it). (On the style benchmark's frames the global search never lowered a distance:
        # elsewhere the residual is the local one.)
        worst = float(d.max())
        if worst > self.max_fit_error:
            far = d > max(3.0 * float(np.median(d)), 0.5 * self._m_per_px)
            s_g = _project_global(ctrl2, p2[far], 8 * (self.degree + 1), 4)
            d[far] = np.minimum(d[far], _dist(ctrl2, p2[far], s_g))
        if d.max() > self.max_fit_error:
            return self._fail('poor_fit', f'the curve misses a centreline point by '
                                          f'{1e3 * d.max():.2f} mm', tm, t0, length=length)
        ctrl3 = ctrl2 @ self._plane.T + self._origin
        t6 = time.perf_counter()
        tm['ends'] = tm.get('ends', 0.0)
        tm['fit'] = t6 - t5
        tm['total'] = t6 - t0
        return Observation(ok=True, status='ok', points=pts3, control_points=ctrl3,
                           residual=float(d.mean()), max_distance=float(d.max()),
                           length=float(length), pixels=px, tip_px=px[-1].copy(),
                           base_px=px[0].copy(), contrast=contrast, timings=tm,
                           area_px=seg.area, bridged=seg.bridged, base_cut=cl.base_cut,
                           roi=(seg.offset[0], seg.offset[1], seg.mask.shape[1],
                                seg.mask.shape[0]),
                           mask=seg.mask if self.keep_mask else None)

    def _fail(self, status: str, message: str, tm: Dict[str, float], t0: float,
              length: float = float('nan')) -> Observation:
        tm['total'] = time.perf_counter() - t0
        return Observation(ok=False, status=status, message=message, length=float(length),
                           control_points=np.full((self.degree + 1, 3), np.nan), timings=tm)
