"""Synthetic camera: draws a catheter centreline as a tube in a fluoroscopy-like frame.

It is the ground truth for tests and benchmarks and the camera of the simulated slave.
Pure numpy/OpenCV; no rclpy.

Geometry. The catheter_base frame (x along the undeformed catheter, y in the bending plane)
is mapped to pixels by a similarity: the base (clamp) sits at pixel `base_px`, the +x axis
points along the image direction `angle` (rad; 0 = +u (right), pi/2 = up, -pi/2 = down) and
+y is +x turned a quarter turn counter-clockwise as seen on the screen. `psi` is the thesis's
3x4 calibration matrix (Eq. 1): (x, y, z)^T = psi (u, v, 0, 1)^T with u the column and v the
row of a pixel centre, z = 0.

Appearance. A bright background with vignetting and smooth texture, the clamp (a dark jaw
behind the base, part of the background), the catheter as a dark tube of its real diameter
(7 Fr = 2.33 mm; darker core, lighter rim, anti-aliased sub-pixel edges), darker
radio-opaque electrodes near the tip (a 4 mm tip electrode and three 1 mm rings), a flat
tip end, a slight blur, additive Gaussian noise, and optionally tissue that hides the last
`tissue_depth` metres of the catheter (the tissue is static, so it is in the background
frame too).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

from catheter_shape.scene import sub_polyline

__all__ = ['SyntheticCamera', 'SyntheticFrame', 'make_psi', 'psi_to_pixels', 'pixels_to_metres',
           'BLAZER_DIAMETER', 'SYSTEM_CAMERA', 'system_psi']

#: Blazer II-XP outer diameter, 7 Fr, m
BLAZER_DIAMETER = 7.0 / 3.0 * 1e-3
_SHIFT = 4                     # OpenCV sub-pixel bits for drawing (1/16 px)
_SCALE = float(1 << _SHIFT)


def make_psi(mm_per_px: float, base_px, angle: float = 0.0) -> np.ndarray:
    """The 3x4 calibration matrix (Eq. 1) of a similarity camera: scale mm_per_px
    (mm/pixel), the base at pixel base_px (u, v), +x along the image direction `angle` (rad)."""
    s = float(mm_per_px) * 1e-3
    if not (np.isfinite(s) and s > 0):
        raise ValueError(f'mm_per_px must be positive and finite, got {mm_per_px!r}')
    b = np.asarray(base_px, dtype=float).reshape(-1)
    if b.shape != (2,) or not np.all(np.isfinite(b)):
        raise ValueError(f'base_px must be 2 finite numbers (u, v), got {base_px!r}')
    if not np.isfinite(angle):
        raise ValueError(f'angle must be finite, got {angle!r}')
    ex = np.array([np.cos(angle), -np.sin(angle)])      # +x in (u, v)
    ey = np.array([-np.sin(angle), -np.cos(angle)])     # +y in (u, v)
    psi = np.zeros((3, 4))
    psi[0, :2] = s * ex
    psi[1, :2] = s * ey
    psi[0, 3] = -s * ex @ b
    psi[1, 3] = -s * ey @ b
    return psi


#: THE calibration of the system's camera, defined once: the simulated fluoroscope of
#: sim_slave's camera_node (its defaults) and shape_node's default psi/base_px, i.e. the force
#: estimator's training camera (force_estimator.dataset.TRAIN_CAMERA is this dict; the model
#: files fingerprint the control points it gives). 800 x 800 px at 0.15 mm/px, the clamp
#: (catheter_base origin) at pixel (u, v) = (260, 400), +x to the right: every Blazer shape
#: with a tip force up to 0.3 N stays in view.
SYSTEM_CAMERA = dict(width=800, height=800, mm_per_px=0.15, base_px=(260.0, 400.0), angle=0.0)


def system_psi() -> np.ndarray:
    """The 3x4 calibration matrix (Eq. 1) of `SYSTEM_CAMERA` (a fresh array)."""
    c = SYSTEM_CAMERA
    return make_psi(c['mm_per_px'], c['base_px'], c['angle'])


def _check_psi(psi) -> np.ndarray:
    p = np.asarray(psi, dtype=float)
    if p.size != 12:
        raise ValueError(f'psi must be 3x4 (or 12 numbers), got shape {p.shape}')
    p = p.reshape(3, 4)
    if not np.all(np.isfinite(p)):
        raise ValueError('psi contains non-finite values')
    if np.linalg.matrix_rank(p[:, :2]) < 2:
        raise ValueError('psi maps the image plane to a line (rank of psi[:, :2] < 2)')
    return p


def pixels_to_metres(psi, uv) -> np.ndarray:
    """Eq. 1: pixel coordinates (N, 2) (u = column, v = row) -> points (N, 3) m."""
    p = _check_psi(psi)
    uv = np.asarray(uv, dtype=float).reshape(-1, 2)
    return uv @ p[:, :2].T + p[:, 3]


def psi_to_pixels(psi, xyz) -> np.ndarray:
    """Inverse of Eq. 1 on the image plane: points (N, 2 or 3) m -> pixels (N, 2).

    With (N, 2) input z is taken as the plane's own; (N, 3) is projected in least squares."""
    p = _check_psi(psi)
    x = np.asarray(xyz, dtype=float)
    x = x.reshape(-1, x.shape[-1]) if x.ndim else x.reshape(-1, 1)
    if x.shape[1] == 2:
        A = p[:2, :2]
        return np.linalg.solve(A, (x - p[:2, 3]).T).T
    if x.shape[1] == 3:
        return np.linalg.lstsq(p[:, :2], (x - p[:, 3]).T, rcond=None)[0].T
    raise ValueError(f'points must be (N, 2) or (N, 3), got {x.shape}')


@dataclass
class SyntheticFrame:
    """One rendered frame.

    image: uint8 (H, W) frame; background: uint8 (H, W), the same scene without the catheter;
    psi: (3, 4) calibration (Eq. 1); centerline_m: (k, 2) m, base -> tip (as given);
    centerline_px: (k, 2) pixels (u, v); visible_centerline_m: (j, 2) m, the part not hidden
    by tissue; in_view: True when the whole tube lies inside the image."""
    image: np.ndarray
    background: np.ndarray
    psi: np.ndarray
    centerline_m: np.ndarray
    centerline_px: np.ndarray
    visible_centerline_m: np.ndarray
    in_view: bool


class SyntheticCamera:
    """A fluoroscopy-like camera looking at the bending plane of the catheter.

    width, height: pixels. mm_per_px: scale, mm per pixel. base_px: (u, v) pixel of the
    clamp point (catheter_base origin); default (0.08 width, height / 2). angle: image
    direction of the catheter's +x axis, rad (0 = right). diameter: tube diameter, m.
    noise: std of the additive Gaussian noise, grey levels (0-255). blur: Gaussian blur
    sigma, pixels (0 = none). vignetting: relative brightness loss at the corners (0-0.5).
    clamp: draw the clamp jaw behind the base (only if the base is in the image).
    electrodes: draw the tip and ring electrodes. seed: seeds the background texture and
    the noise (render(rng=...) overrides the noise draw per frame). One render at a time per
    camera (its noise generator and tissue mask are its own: not thread-safe).
    """

    def __init__(self, width: int = 640, height: int = 480, mm_per_px: float = 0.15,
                 base_px=None, angle: float = 0.0, diameter: float = BLAZER_DIAMETER,
                 noise: float = 4.0, blur: float = 0.7, vignetting: float = 0.2,
                 clamp: bool = True, electrodes: bool = True, seed: int = 0):
        for name, v in (('width', width), ('height', height)):
            if int(v) != v or not (16 <= v <= 8192):
                raise ValueError(f'{name} must be an integer in [16, 8192], got {v!r}')
        for name, v, lo, hi in (('noise', noise, 0.0, 100.0), ('blur', blur, 0.0, 10.0),
                                ('vignetting', vignetting, 0.0, 0.5),
                                ('diameter', diameter, 1e-5, 0.05)):
            if not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f'{name} must be in [{lo}, {hi}], got {v!r}')
        self.width, self.height = int(width), int(height)
        self.mm_per_px = float(mm_per_px)
        if base_px is None:
            base_px = (0.08 * self.width, self.height / 2.0)
        self.base_px = tuple(float(b) for b in np.asarray(base_px, dtype=float).reshape(2))
        self.angle = float(angle)
        self.psi = make_psi(mm_per_px, self.base_px, angle)
        self.diameter = float(diameter)
        self.noise = float(noise)
        self.blur = float(blur)
        self.vignetting = float(vignetting)
        self.clamp = bool(clamp)
        self.electrodes = bool(electrodes)
        self.seed = int(seed)
        self._px_per_m = 1e3 / self.mm_per_px
        self._ex = np.array([np.cos(angle), -np.sin(angle)])
        self._ey = np.array([-np.sin(angle), -np.cos(angle)])
        rng = np.random.default_rng(self.seed)
        self._bg = self._make_background(rng)                      # float32
        self.background = np.clip(np.rint(self._bg), 0, 255).astype(np.uint8)
        # the frame outside the tube is trunc(clip(bg + noise)) in one OpenCV pass to uint8,
        # which rounds to nearest: so bg - 1/2 (round(y - 1/2) = floor(y) but where y is
        # within a float32 rounding of an integer); without noise, the truncated background
        self._bg_half = self._bg - np.float32(0.5)
        self._bg_trunc = np.clip(self._bg, 0, 255).astype(np.uint8)
        self._pad = 64
        if self.noise > 0:
            self._bank = (rng.standard_normal((2, self.height + self._pad, self.width + self._pad))
                          .astype(np.float32) * np.float32(self.noise))
        else:
            self._bank = None
        self._rng = rng

    @classmethod
    def framing(cls, length: float = 0.065, width: int = 640, height: int = 480,
                margin_px: int = 20, **kwargs) -> 'SyntheticCamera':
        """A camera that sees every planar shape of a clamped catheter of this length
        (m) under tip loads: x in [-0.5, 1] length, y in [-0.9, 0.9] length (the Blazer
        under 0.3 N at any angle stays inside). The catheter points down the image (as in
        the thesis's set-up), the clamp near the top. Other keyword arguments go to the
        constructor (noise, blur, seed, ...)."""
        if not (np.isfinite(length) and length > 0):
            raise ValueError(f'length must be positive, got {length!r}')
        x_span = 1.5 * length * 1e3                        # mm along the image rows
        y_span = 1.8 * length * 1e3                        # mm along the columns
        mm = max(x_span / (height - 2 * margin_px), y_span / (width - 2 * margin_px))
        base = (width / 2.0, margin_px + 0.5 * length * 1e3 / mm)
        return cls(width=width, height=height, mm_per_px=mm, base_px=base, angle=-np.pi / 2,
                   **kwargs)

    # --- geometry -------------------------------------------------------------------
    def to_pixels(self, xy) -> np.ndarray:
        """catheter_base points (N, 2) m -> pixels (N, 2) (u, v)."""
        xy = np.asarray(xy, dtype=float)
        return (np.asarray(self.base_px) + (xy[:, :1] * self._ex + xy[:, 1:2] * self._ey)
                * self._px_per_m)

    def to_metres(self, uv) -> np.ndarray:
        """Pixels (N, 2) -> catheter_base points (N, 2) m."""
        d = (np.asarray(uv, dtype=float) - np.asarray(self.base_px)) / self._px_per_m
        return np.stack([d @ self._ex, d @ self._ey], axis=1)

    @property
    def radius_px(self) -> float:
        return 0.5 * self.diameter * self._px_per_m

    def base_in_view(self) -> bool:
        u, v = self.base_px
        return 0 <= u <= self.width - 1 and 0 <= v <= self.height - 1

    # --- background -----------------------------------------------------------------
    def _make_background(self, rng) -> np.ndarray:
        H, W = self.height, self.width
        v, u = np.mgrid[0:H, 0:W].astype(np.float32)
        r2 = ((u - W / 2) ** 2 + (v - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
        bg = 215.0 * (1.0 - self.vignetting * r2)
        # smooth texture (anatomy-like low-frequency structure), +- ~6 grey levels
        small = rng.standard_normal((max(4, H // 16), max(4, W // 16))).astype(np.float32)
        tex = cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)
        tex = cv2.GaussianBlur(tex, (0, 0), 6.0)
        tex *= 6.0 / (tex.std() + 1e-6)
        bg = (bg + tex).astype(np.float32)
        if self.clamp and self.base_in_view():
            # the clamp jaw: a dark block behind the base, x in [-8, 0] mm, |y| <= 3 mm
            ppm = self._px_per_m
            b = np.asarray(self.base_px)
            corners = np.array([b + (-0.008 * self._ex - 0.003 * self._ey) * ppm,
                                b + (0.0 * self._ex - 0.003 * self._ey) * ppm,
                                b + (0.0 * self._ex + 0.003 * self._ey) * ppm,
                                b + (-0.008 * self._ex + 0.003 * self._ey) * ppm])
            m = np.zeros((H, W), np.uint8)
            cv2.fillConvexPoly(m, np.rint(corners * _SCALE).astype(np.int32), 255,
                               cv2.LINE_AA, _SHIFT)
            a = m.astype(np.float32) / 255.0
            bg = bg * (1 - a) + 40.0 * a
            self._clamp_mask = m
        else:
            self._clamp_mask = None
        if self.blur > 0:
            bg = cv2.GaussianBlur(bg, (0, 0), self.blur)
        return bg

    # --- rendering ------------------------------------------------------------------
    def render(self, centerline_m, rng: Optional[np.random.Generator] = None,
               tissue_depth: float = 0.0) -> SyntheticFrame:
        """Draw a catheter with centreline (k, 2) m (or (k, 3) with z ignored), base -> tip,
        in catheter_base. rng: noise generator for this frame (default: the camera's own).
        tissue_depth: m of the catheter (from the tip) hidden under tissue (0 = none).
        Returns a SyntheticFrame."""
        c = np.asarray(centerline_m, dtype=float)
        if c.ndim != 2 or c.shape[1] not in (2, 3) or c.shape[0] < 2:
            raise ValueError(f'centerline_m must have shape (k>=2, 2|3), got {c.shape}')
        if not np.all(np.isfinite(c)):
            raise ValueError('centerline_m contains non-finite values')
        if not (np.isfinite(tissue_depth) and tissue_depth >= 0):
            raise ValueError(f'tissue_depth must be >= 0, got {tissue_depth!r}')
        c = c[:, :2]
        seg = np.sqrt(np.sum(np.diff(c, axis=0) ** 2, axis=1))
        keep = np.concatenate([[True], seg > 1e-12])
        c = c[keep]
        if c.shape[0] < 2:
            raise ValueError('centerline_m has zero length')
        rng = self._rng if rng is None else rng
        H, W = self.height, self.width
        px = self.to_pixels(c)
        s_m = np.concatenate([[0.0], np.cumsum(np.sqrt(np.sum(np.diff(c, axis=0) ** 2, axis=1)))])
        L = s_m[-1]
        r = self.radius_px
        # crop: the tube's bounding box plus a margin, clipped to the image
        m = int(np.ceil(r + 4 + 3 * self.blur))
        u0 = max(int(np.floor(px[:, 0].min())) - m, 0)
        v0 = max(int(np.floor(px[:, 1].min())) - m, 0)
        u1 = min(int(np.ceil(px[:, 0].max())) + m + 1, W)
        v1 = min(int(np.ceil(px[:, 1].max())) + m + 1, H)
        in_view = bool(px[:, 0].min() - r >= 0 and px[:, 1].min() - r >= 0
                       and px[:, 0].max() + r <= W - 1 and px[:, 1].max() + r <= H - 1)
        bg = self._bg
        visible = c
        if tissue_depth > 0:
            bg, visible = self._tissue(c, px, s_m, tissue_depth)
        # the frame in uint8 at once (bg + noise, truncated: one pass); the tube's box is then
        # composed in float32 and truncated the same way (a full float32 frame, clipped and
        # converted, cost twice the pass)
        noise = None
        if self._bank is not None:
            k = int(rng.integers(2))
            dy, dx = (int(x) for x in rng.integers(0, self._pad, 2))
            noise = self._bank[k, dy:dy + H, dx:dx + W]
            half = self._bg_half if tissue_depth <= 0 else bg - np.float32(0.5)
            image = cv2.add(half, noise, dtype=cv2.CV_8U)
        elif tissue_depth <= 0:
            image = self._bg_trunc.copy()
        else:
            image = np.clip(bg, 0, 255).astype(np.uint8)
        if u1 > u0 and v1 > v0:
            cw, ch = u1 - u0, v1 - v0
            off = np.array([u0, v0], dtype=float)
            alpha = np.zeros((ch, cw), np.uint8)    # coverage
            level = np.zeros((ch, cw), np.uint8)    # darkness of the covered part
            # draw through points about 3 px apart (thick anti-aliased polylines cost per
            # segment; the chord sag at 3 px is < 0.06 px for radii above 20 px)
            s_px = s_m * self._px_per_m
            n_draw = int(np.ceil(s_px[-1] / 3.0)) + 1
            if n_draw < px.shape[0]:
                sd = np.linspace(0.0, s_px[-1], n_draw)
                pd = np.stack([np.interp(sd, s_px, px[:, 0]), np.interp(sd, s_px, px[:, 1])], 1)
            else:
                pd = px
            pts = np.rint((pd - off) * _SCALE).astype(np.int32).reshape(-1, 1, 2)
            d = 2.0 * r
            cv2.polylines(alpha, [pts], False, 255, max(1, int(round(d))), cv2.LINE_AA, _SHIFT)
            for frac, val in ((1.0, 150), (0.7, 190), (0.4, 215)):
                cv2.polylines(level, [pts], False, val, max(1, int(round(frac * d))),
                              cv2.LINE_AA, _SHIFT)
            if self.electrodes:
                for a, b in ((0.0, 0.004), (0.006, 0.007), (0.009, 0.010), (0.012, 0.013)):
                    sel = sub_polyline(px - off, s_m, L - b, L - a)
                    if sel is not None:
                        cv2.polylines(level, [np.rint(sel * _SCALE).astype(np.int32)
                                              .reshape(-1, 1, 2)], False, 245,
                                      max(1, int(round(0.8 * d))), cv2.LINE_AA, _SHIFT)
            # flat ends: cut the round caps OpenCV draws beyond the tip (and the base)
            ends = [(px[-1] - off, px[-1] - px[-2])]
            if self._clamp_mask is None:
                ends.append((px[0] - off, px[0] - px[1]))
            for p_end, t in ends:
                t = t / (np.linalg.norm(t) + 1e-12)
                n = np.array([-t[1], t[0]])
                e = r + 3.0
                quad = np.array([p_end + e * n, p_end + e * n + 2 * e * t,
                                 p_end - e * n + 2 * e * t, p_end - e * n])
                q = np.rint(quad * _SCALE).astype(np.int32)
                cv2.fillConvexPoly(alpha, q, 0, cv2.LINE_AA, _SHIFT)
            a = alpha.astype(np.float32) * np.float32(1.0 / 255.0)
            if self._clamp_mask is not None:
                a *= 1.0 - self._clamp_mask[v0:v1, u0:u1].astype(np.float32) / 255.0
            if tissue_depth > 0:
                a *= 1.0 - self._tissue_mask[v0:v1, u0:u1].astype(np.float32) / 255.0
            dark = 40.0 - level.astype(np.float32) * np.float32(35.0 / 255.0)   # 40 .. 5
            if self.blur > 0:
                k = int(2 * np.ceil(3 * self.blur) + 1)
                a = cv2.GaussianBlur(a, (k, k), self.blur)
                dark = cv2.GaussianBlur(dark, (k, k), self.blur)
            bgb = bg[v0:v1, u0:u1]
            sub = bgb + noise[v0:v1, u0:u1] if noise is not None else bgb.copy()
            sub += a * (dark - bgb)
            np.clip(sub, 0, 255, out=sub)
            image[v0:v1, u0:u1] = sub
        background = self.background if tissue_depth <= 0 else \
            np.clip(np.rint(bg), 0, 255).astype(np.uint8)
        return SyntheticFrame(image=image, background=background, psi=self.psi.copy(),
                              centerline_m=c, centerline_px=px, visible_centerline_m=visible,
                              in_view=in_view)

    def _tissue(self, c, px, s_m, depth):
        """Background with a tissue blob hiding the last `depth` m; the visible centreline."""
        L = s_m[-1]
        depth = min(depth, 0.9 * L)
        t = px[-1] - px[max(len(px) - 4, 0)]
        t = t / (np.linalg.norm(t) + 1e-12)
        R = 0.012 * self._px_per_m                     # 12 mm radius tissue blob
        p_surf = np.array([np.interp(L - depth, s_m, px[:, 0]),
                           np.interp(L - depth, s_m, px[:, 1])])
        centre = p_surf + R * t
        m = np.zeros((self.height, self.width), np.uint8)
        cv2.circle(m, tuple(int(x) for x in np.rint(centre * _SCALE)), int(round(R * _SCALE)), 255,
                   -1, cv2.LINE_AA, _SHIFT)
        a = m.astype(np.float32) / 255.0
        tex = getattr(self, '_tissue_tex', None)
        if tex is None:                                  # static texture: computed once
            v, u = np.mgrid[0:self.height, 0:self.width]
            tex = (150.0 + 12.0 * np.sin(u * 0.21 + 0.5 * np.sin(v * 0.13)) * np.cos(v * 0.17)
                   ).astype(np.float32)
            self._tissue_tex = tex
        bg = self._bg + a * (tex - self._bg)
        self._tissue_mask = m
        d = np.sqrt(np.sum((px - centre) ** 2, axis=1))
        outside = d > R
        first_in = int(np.argmin(outside)) if not outside.all() else len(px)
        vis = c[:max(first_in, 2)]
        return bg, vis
