"""Drawing primitives of the camera-style renderer (catheter_shape.styles): scene layers
(texture, anatomy, vessels, wires, tissue patches, clamp and sheath), the catheter's
thickness and electrode maps, motion blur and the exposure (noise, quantisation, JPEG).

Images are float32 (H, W) light or transmission maps until `expose` turns them into uint8
or uint16 frames. Pure numpy/OpenCV; no rclpy.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ['SHIFT', 'SCALE', 'ELECTRODES', 'smooth_noise', 'anatomy', 'vessel', 'wires',
           'patch', 'clamp', 'catheter_layers', 'motion', 'expose']

#: OpenCV sub-pixel bits for drawing (1/16 px)
SHIFT = 4
SCALE = float(1 << SHIFT)
#: electrode bands (from the tip, m): a 4 mm tip electrode and three 1 mm rings
ELECTRODES = ((0.0, 0.004), (0.006, 0.007), (0.009, 0.010), (0.012, 0.013))


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def smooth_noise(rng, H, W, cell, amp):
    small = rng.standard_normal((max(3, H // cell + 2), max(3, W // cell + 2))).astype(np.float32)
    t = cv2.resize(small, (W, H), interpolation=cv2.INTER_CUBIC)
    t = cv2.GaussianBlur(t, (0, 0), max(cell / 3.0, 1.0))
    return t * np.float32(amp / (t.std() + 1e-6))


def anatomy(rng, H, W, mm_per_px) -> np.ndarray:
    """Transmission (H, W) of ribs, vessels and a spine-like block (float32, <= 1)."""
    v, u = np.mgrid[0:H, 0:W].astype(np.float32)
    T = np.ones((H, W), np.float32)
    # ribs: curved periodic bands across the image
    a = _u(rng, 0, np.pi)
    along = u * np.cos(a) + v * np.sin(a)
    across = -u * np.sin(a) + v * np.cos(a)
    period = _u(rng, 12, 22) / mm_per_px
    bend = _u(rng, -1.5e-3, 1.5e-3)
    phase = (across + bend * (along - along.mean()) ** 2) / period
    frac = phase - np.floor(phase)
    width = _u(rng, 0.3, 0.5)                   # fraction of the period covered by a rib
    rib = np.clip((0.5 * width - np.abs(frac - 0.5)) * period / 3.0, 0, 1).astype(np.float32)
    rib = cv2.GaussianBlur(rib, (0, 0), 2.0)
    T *= 1.0 - _u(rng, 0.1, 0.25) * rib
    # vessels: bright and dark smooth bands about the catheter's width
    for _ in range(int(rng.integers(2, 5))):
        m = np.zeros((H, W), np.uint8)
        pts = np.cumsum(rng.normal(0, 40, (8, 2)), axis=0) + [_u(rng, 0, W), _u(rng, 0, H)]
        wv = max(1, int(round(_u(rng, 1.5, 4.0) / mm_per_px)))
        cv2.polylines(m, [np.rint(pts * SCALE).astype(np.int32).reshape(-1, 1, 2)], False,
                      255, wv, cv2.LINE_AA, SHIFT)
        k = cv2.GaussianBlur(m.astype(np.float32) / 255.0, (0, 0), 1.5)
        sign = -1.0 if rng.random() < 0.5 else 1.0
        T *= 1.0 + sign * _u(rng, 0.05, 0.2) * k
    # a spine-like block
    if rng.random() < 0.5:
        c0 = _u(rng, 0.2, 0.8) * W
        w = _u(rng, 15, 30) / mm_per_px
        s = np.clip(1 - np.abs(u - c0) / w, 0, 1) ** 0.5
        T *= 1.0 - _u(rng, 0.1, 0.25) * s.astype(np.float32)
    return T


def vessel(rng, H, W, mm_per_px) -> np.ndarray:
    """Transmission (H, W) of a contrast-filled vessel (a dark tube 2-5 mm wide along a
    smooth random curve) and a pacing lead (a 1.5 mm dark line)."""
    T = np.ones((H, W), np.float32)
    for width_mm, dark in ((_u(rng, 2.0, 5.0), _u(rng, 0.3, 0.55)), (1.5, _u(rng, 0.2, 0.4))):
        m = np.zeros((H, W), np.uint8)
        a = _u(rng, 0, 2 * np.pi)
        pts = [np.array([_u(rng, 0, W), _u(rng, 0, H)])]
        for _ in range(14):
            a += rng.normal(0, 0.2)
            pts.append(pts[-1] + 50.0 * np.array([np.cos(a), np.sin(a)]))
        pts = np.array(pts)
        cv2.polylines(m, [np.rint(pts * SCALE).astype(np.int32).reshape(-1, 1, 2)], False, 255,
                      max(1, int(round(width_mm / mm_per_px))), cv2.LINE_AA, SHIFT)
        k = cv2.GaussianBlur(m.astype(np.float32) / 255.0, (0, 0), 1.0)
        T *= 1.0 - np.float32(dark) * k
    return T


def wires(rng, H, W, mm_per_px, n) -> np.ndarray:
    """Transmission (H, W) of n thin dark wires (ECG leads) across the image."""
    T = np.ones((H, W), np.float32)
    for _ in range(n):
        m = np.zeros((H, W), np.uint8)
        start = np.array([_u(rng, 0, W), _u(rng, 0, H)])
        a = _u(rng, 0, 2 * np.pi)
        pts = [start]
        for _ in range(12):
            a += rng.normal(0, 0.25)
            pts.append(pts[-1] + 60.0 * np.array([np.cos(a), np.sin(a)]))
        pts = np.array(pts)
        wv = max(1, int(round(_u(rng, 0.4, 0.9) / mm_per_px)))
        cv2.polylines(m, [np.rint(pts * SCALE).astype(np.int32).reshape(-1, 1, 2)], False,
                      255, wv, cv2.LINE_AA, SHIFT)
        T *= 1.0 - np.float32(_u(rng, 0.3, 0.7)) * m.astype(np.float32) / np.float32(255.0)
    return T


def patch(rng, H, W, centre, r_px, tex_amp=0.05) -> np.ndarray:
    """Soft elliptical patch mask (H, W) float32 in [0, 1] around centre."""
    m = np.zeros((H, W), np.uint8)
    axes = (max(1, int(r_px * _u(rng, 0.8, 1.3))), max(1, int(r_px * _u(rng, 0.6, 1.0))))
    cv2.ellipse(m, (int(centre[0]), int(centre[1])), axes, _u(rng, 0, 180), 0, 360, 255, -1,
                cv2.LINE_AA)
    return cv2.GaussianBlur(m.astype(np.float32) / 255.0, (0, 0), 3.0)


def clamp(kind, base, ex, ey, ppm, H, W):
    """Mask of the clamp jaw (behind the base) or an introducer sheath (a wider tube along
    -x ending at the base). float32 (H, W) in [0, 1]."""
    m = np.zeros((H, W), np.uint8)
    if kind == 'jaw':
        corners = [base + (a * ex + b * ey) * ppm for a, b in
                   ((-0.008, -0.003), (0.0, -0.003), (0.0, 0.003), (-0.008, 0.003))]
        cv2.fillConvexPoly(m, np.rint(np.array(corners) * SCALE).astype(np.int32), 255,
                           cv2.LINE_AA, SHIFT)
    elif kind == 'sheath':
        p0 = base - 0.04 * ex * ppm
        pts = np.rint(np.array([p0, base]) * SCALE).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(m, [pts], False, 255, max(1, int(round(0.0035 * ppm))), cv2.LINE_AA, SHIFT)
        # flat end at the base
        q = [base + (a * ex + b * ey) * ppm for a, b in
             ((0.0, -0.004), (0.004, -0.004), (0.004, 0.004), (0.0, 0.004))]
        cv2.fillConvexPoly(m, np.rint(np.array(q) * SCALE).astype(np.int32), 0, cv2.LINE_AA,
                           SHIFT)
    return m.astype(np.float32) / 255.0


def sub_polyline(px: np.ndarray, s: np.ndarray, a: float, b: float):
    """The polyline px (k, 2) between arc lengths a < b (s: arc length of each point),
    interpolated at both ends; None when the interval is empty."""
    a, b = max(a, 0.0), min(b, s[-1])
    if b - a <= 0:
        return None
    inside = (s > a) & (s < b)
    pa = np.array([np.interp(a, s, px[:, 0]), np.interp(a, s, px[:, 1])])
    pb = np.array([np.interp(b, s, px[:, 0]), np.interp(b, s, px[:, 1])])
    return np.vstack([pa, px[inside], pb])


def catheter_layers(px, s_m, r_px, H, W, lumen, bands=6):
    """Thickness map (relative to the core's chord, 0..1) and electrode coverage (0..1) of a
    tube along the polyline px (k, 2), with a flat tip end. Solid rod chord profile
    sqrt(1 - (r/R)^2) as `bands` nested anti-aliased bands, minus a lighter lumen."""
    thick = np.zeros((H, W), np.float32)
    L = s_m[-1]
    s_px = s_m / L * np.sum(np.linalg.norm(np.diff(px, axis=0), axis=1))
    n_draw = int(np.ceil(s_px[-1] / 3.0)) + 1
    sd = np.linspace(0.0, s_px[-1], max(n_draw, 2))
    pd = np.stack([np.interp(sd, s_px, px[:, 0]), np.interp(sd, s_px, px[:, 1])], 1)
    pts = np.rint(pd * SCALE).astype(np.int32).reshape(-1, 1, 2)
    canvas = np.zeros((H, W), np.uint8)
    for k in range(bands):
        r = r_px * np.sqrt(1.0 - ((k + 0.5) / bands) ** 2)
        canvas[:] = 0
        cv2.polylines(canvas, [pts], False, 255, max(1, int(round(2 * r))), cv2.LINE_AA, SHIFT)
        thick += canvas.astype(np.float32) * np.float32(1.0 / (255.0 * bands))
    if lumen > 0:
        canvas[:] = 0
        cv2.polylines(canvas, [pts], False, 255, max(1, int(round(2 * 0.75 * r_px))),
                      cv2.LINE_AA, SHIFT)
        thick -= canvas.astype(np.float32) * np.float32(lumen * 0.4 / 255.0)
    elec = np.zeros((H, W), np.uint8)
    for a, b in ELECTRODES:
        sel = sub_polyline(px, s_m, L - b, L - a)
        if sel is not None:
            cv2.polylines(elec, [np.rint(sel * SCALE).astype(np.int32).reshape(-1, 1, 2)], False,
                          255, max(1, int(round(2 * r_px))), cv2.LINE_AA, SHIFT)
    # flat ends: cut the round caps beyond the tip and the base
    cut = np.full((H, W), 255, np.uint8)
    for p_end, t in ((px[-1], px[-1] - px[-2]), (px[0], px[0] - px[1])):
        t = t / (np.linalg.norm(t) + 1e-12)
        n = np.array([-t[1], t[0]])
        e = r_px + 3.0
        quad = np.array([p_end + e * n, p_end + e * n + 2 * e * t, p_end - e * n + 2 * e * t,
                         p_end - e * n])
        cv2.fillConvexPoly(cut, np.rint(quad * SCALE).astype(np.int32), 0, cv2.LINE_AA, SHIFT)
    keep = cut.astype(np.float32) / 255.0
    return np.clip(thick, 0, 1) * keep, elec.astype(np.float32) / 255.0 * keep


def motion(img: np.ndarray, length: float, angle: float) -> np.ndarray:
    if length < 1.0:
        return img
    k = int(np.ceil(length)) | 1
    ker = np.zeros((k, k), np.float32)
    c = k // 2
    d = np.array([np.cos(angle), np.sin(angle)])
    for t in np.linspace(-length / 2, length / 2, 4 * k):
        x, y = c + t * d
        ker[int(round(y)), int(round(x))] += 1.0
    ker /= ker.sum()
    return cv2.filter2D(img, -1, ker, borderType=cv2.BORDER_REPLICATE)


def expose(light: np.ndarray, p: dict, gain: float, rng, frames: int = 1) -> np.ndarray:
    """Light (relative, ~1 = the style's level) -> noisy quantised image (uint8 or uint16)."""
    img = light * np.float32(p['level'] * gain)
    if p['blur'] > 0:
        img = cv2.GaussianBlur(img, (0, 0), p['blur'])
    # Poisson-Gaussian noise: variance = read^2 + k * signal, noise std `noise` at 200 grey
    read = 0.4 * p['noise']
    k = (p['noise'] ** 2 - read ** 2) / 200.0
    std = np.sqrt(read ** 2 + k * np.maximum(img, 0)) / np.sqrt(frames)
    img = img + std * rng.standard_normal(img.shape, dtype=np.float32) + np.float32(p['black'])
    if p['bits'] == 16:
        out = np.clip(np.rint(img * (4095.0 / 255.0)), 0, 4095).astype(np.uint16) * np.uint16(16)
        return out
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if p['jpeg']:
        ok, buf = cv2.imencode('.jpg', out, [cv2.IMWRITE_JPEG_QUALITY, int(p['jpeg'])])
        out = cv2.imdecode(buf, cv2.IMREAD_GRAYSCALE)
    return out
