"""Illumination-independent segmentation: the catheter's relative darkness after a divisive
flat-field correction, and a threshold at half of the catheter's own contrast.

Why divide. Whatever makes the image (X-ray attenuation, an optical camera's reflectance,
vignetting, exposure), the light that reaches a pixel is the illumination times what the
scene lets through; a catheter MULTIPLIES the local light by its transmission (or
reflectance). The standard flat-field correction, frame / background, removes the
illumination and the static scene, so the catheter's darkness

    d = 1 - frame / (g * background)

is the same over a bright or a dark part of the scene, with or without vignetting, and
whatever the exposure: g, the frame's exposure relative to the background frame, is the
median of frame / background over the pixels saturated in neither (the catheter covers a
few per cent of the image); where g * background exceeds the full scale the frame is
compared with the full scale (it saturates there). The
thesis's subtractive correction `255 - max(background - frame, 0)` and its fixed threshold
of 132 measure darkness in grey levels, so a catheter that transmits 35 % of the light is
123 grey levels darker than a 190 background but only 65 darker than a 100 one: it breaks
into fragments wherever the scene or the vignetting is dark.

Level. The catheter's own contrast c (the median darkness of the pixels clearly above the
noise, d > 6 sigma, sigma from the median absolute deviation of d; where the catheter
leaves the clamp when the clamp pixel is known, so that clutter elsewhere does not count) sets the
threshold c / 2: the half-contrast edge, unbiased for a symmetric blur, from faint (c ~ 0.15) to
saturated (c ~ 1) catheters. The darkness is smoothed first by a Gaussian of about a
tenth of the catheter's width (faint catheters: the noise drops 5-10x, the centreline and
the half-contrast tip end do not move; two passes of a box filter, which is nearly Gaussian
and several times cheaper).

Without a background frame the background is estimated from the frame itself: a grey
closing (max then min filter) wider than the catheter removes every dark structure
narrower than about twice the catheter's width, which is the catheter (and anything else
that narrow). Dark structures of that size in the scene (ribs, vessels, a clamp edge) are
then segmented too: the sensor refuses those frames or picks the catheter by the clamp
pixel; a background frame is the remedy.

Pure numpy/OpenCV; no rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import cv2
import numpy as np

__all__ = ['Darkness', 'FlatField', 'flat_field', 'local_half_peak', 'prepare_background',
           'estimate_background', 'MIN_CONTRAST', 'SEED_SIGMAS']

#: smallest relative darkness accepted as a catheter (the catheter must dim the light by 6 %)
MIN_CONTRAST = 0.06
#: seeds of the contrast estimate: pixels this many noise sigmas above the background
SEED_SIGMAS = 6.0
#: statistics on every STRIDE-th pixel in each direction (speed)
STRIDE = 8


@dataclass
class FlatField:
    """score: relative darkness (smoothed; 0 = background, 1 = black): a `Darkness` (with a
    background frame: evaluated where it is indexed) or a float32 (H, W) image;
    mask: uint8 0/255, score > level; level: the threshold (half the contrast); contrast: the
    catheter's median darkness; sigma: noise std of the score; gain: frame / background
    exposure (1 without a background); status: 'ok' or 'no_catheter' (nothing above the
    noise)."""
    score: object
    mask: np.ndarray
    level: float
    contrast: float
    sigma: float
    gain: float
    status: str = 'ok'


def smoothing_sigma(width_px: float) -> float:
    """Gaussian sigma (pixels) applied before the division: about a tenth of the width."""
    return float(np.clip(0.12 * width_px, 0.6, 2.5))


def _blur(img: np.ndarray, sigma: float) -> np.ndarray:
    """Two passes of a k x k box filter: a symmetric, nearly Gaussian blur of std
    sqrt((k^2 - 1) / 6) (k odd, >= 3) at a fraction of GaussianBlur's cost."""
    k = max(3, int(round(np.sqrt(6.0 * sigma ** 2 + 1.0))) | 1)
    return cv2.blur(cv2.blur(img, (k, k)), (k, k))


def prepare_background(background: np.ndarray, width_px: float) -> np.ndarray:
    """A background frame (uint8/uint16 grey) smoothed like the frames will be, as float32
    floored at 1 (no division by 0)."""
    b = _blur(background, smoothing_sigma(width_px)).astype(np.float32)
    return np.maximum(b, np.float32(1.0))


def estimate_background(frame: np.ndarray, width_px: float) -> np.ndarray:
    """Background of a float32 frame without the catheter: grey closing with a square of
    about 2 catheter widths + 1 (computed on a copy downsampled by about a quarter width,
    then upsampled: at the sharp edge of a large dark structure the estimate ramps over a
    few pixels, a thin false rim that the sensor's opening removes)."""
    H, W = frame.shape
    s = max(1, int(width_px // 4))
    small = cv2.resize(frame, (max(1, W // s), max(1, H // s)), interpolation=cv2.INTER_AREA) \
        if s > 1 else frame
    k = int(np.ceil((2.0 * width_px + 1.0) / s)) | 1
    ker = cv2.getStructuringElement(cv2.MORPH_RECT, (k, k))
    closed = cv2.morphologyEx(small, cv2.MORPH_CLOSE, ker, borderType=cv2.BORDER_REPLICATE)
    if s > 1:
        closed = cv2.resize(closed, (W, H), interpolation=cv2.INTER_LINEAR)
    return np.maximum(closed, np.float32(1.0))


def _median(x: np.ndarray) -> float:
    """np.median of a 1-d array (NaN when empty) by one partition (np.median's checks cost
    more than the partition on the few thousand samples here)."""
    n = x.size
    if n == 0:
        return float('nan')
    x = x.ravel()
    k = n // 2
    if n % 2:
        return float(np.partition(x, k)[k])
    q = np.partition(x, (k - 1, k))
    return float((q[k - 1] + q[k]) / 2)


class Darkness:
    """The relative darkness `1 - frame / expected` of a frame against a background frame,
    evaluated only where it is read (the sensor reads it at a few hundred points near the
    catheter's ends, and the mask is compared in the frame's own integer units): indexing
    `dark[ys, xs]` with integer arrays returns float32 values, `shape` is the frame's, and
    `np.asarray(dark)` (or `full()`) computes the whole image.

    f: the smoothed frame (integer dtype); background: float32 (same shape, floored at 1);
    gain: the frame's exposure relative to the background; clip: the full scale when the
    expected value g * background must be capped at it (the frame saturates), else None."""

    def __init__(self, f: np.ndarray, background: np.ndarray, gain: float,
                 clip: Optional[float]):
        self.f = f
        self.background = background
        self.gain = float(gain)
        self.clip = clip
        self.shape = f.shape
        self.ndim = 2

    def _of(self, f, b) -> np.ndarray:
        e = b * np.float32(self.gain)
        if self.clip is not None:
            e = np.minimum(e, np.float32(self.clip))
        return np.float32(1.0) - f.astype(np.float32) / e

    def __getitem__(self, index) -> np.ndarray:
        return self._of(self.f[index], self.background[index])

    def full(self) -> np.ndarray:
        """The whole darkness image, float32 (H, W)."""
        return self._of(self.f, self.background)

    def __array__(self, dtype=None, copy=None):
        d = self.full()
        return d if dtype is None else d.astype(dtype)

    def mask(self, level: float) -> np.ndarray:
        """uint8 0/255: darkness > level, i.e. f < (1 - level) * expected, compared in the
        frame's integer units (no full-frame float image)."""
        k = 1.0 - float(level)
        if k <= 0:
            return np.zeros(self.shape, np.uint8)
        if self.f.dtype == np.uint8:
            # f is an integer: f < y  <=>  f < ceil(y); convertScaleAbs rounds to nearest
            t = cv2.convertScaleAbs(self.background, alpha=k * self.gain, beta=0.4999)
            if self.clip is not None:
                t = np.minimum(t, np.uint8(min(255, int(np.ceil(k * self.clip)))))
            return cv2.compare(self.f, t, cv2.CMP_LT)
        t = self.background * np.float32(self.gain)
        if self.clip is not None:
            np.minimum(t, np.float32(self.clip), out=t)
        t *= np.float32(k)
        return cv2.compare(self.f.astype(np.float32), t, cv2.CMP_LT)


def _level(contrast: float, med: float, sigma: float, min_contrast: float) -> float:
    """The threshold: half-way between the background and the catheter's contrast, at
    least 4 noise sigmas above the background and half the smallest contrast."""
    return max(0.5 * (contrast + med), med + 4.0 * sigma, 0.5 * min_contrast)


def flat_field(gray: np.ndarray, background: Optional[np.ndarray], width_px: float,
               full_scale: float = 255.0, min_contrast: float = MIN_CONTRAST,
               base_px=None, base_dir=None, background_max: Optional[float] = None
               ) -> FlatField:
    """Relative darkness of a grey frame (uint8 or uint16 (H, W)) against `background`
    (float32 from `prepare_background`, same shape) or, without one, against
    `estimate_background`; smoothed, thresholded at half the catheter's contrast.

    full_scale: the largest value the frame can hold (255 for uint8; pixels at >= 98 % of
    it are saturated and left out of the exposure estimate). base_px: the clamp pixel
    (u, v), optional, with base_dir the unit pixel direction in which the catheter leaves
    it (+x of catheter_base): when it lies in the frame, the contrast is measured on the
    catheter where it leaves the clamp (a disc of 1.5 widths, 1.5 widths ahead of the clamp
    pixel), so that many small dark structures elsewhere (texture, clutter) cannot pull the
    level down to their own darkness, nor the clamp behind the base push it up.

    background_max: background.max() when the caller knows it (computed otherwise).

    With a background the score is a `Darkness` (evaluated where it is read; the mask is
    compared in integer units); without one a float32 image."""
    # smooth the integer frame (fixed-point, fast), then divide: blur(frame) / blur(bg) is
    # the blurred transmission wherever the background is smooth on the blur's scale
    fi = _blur(gray, smoothing_sigma(width_px))
    if background is not None:
        sat = np.float32(0.98 * full_scale)
        fb = fi[::STRIDE, ::STRIDE].astype(np.float32)
        bb = background[::STRIDE, ::STRIDE]
        use = (fb < sat) & (bb < sat) & (bb > np.float32(0.02 * full_scale))
        gain = _median(fb[use] / bb[use]) if use.sum() > 0.05 * use.size else 1.0
        if not (np.isfinite(gain) and gain > 0):
            gain = 1.0
        # the frame saturates where the background, at the frame's exposure, would be
        # brighter than the full scale: compare with what the frame can hold there
        if background_max is None:
            background_max = cv2.minMaxLoc(background)[1]
        clip = full_scale if gain * background_max > 0.98 * full_scale else None
        d = Darkness(fi, background, gain, clip)
        sub = d[::STRIDE, ::STRIDE].ravel()
    else:
        gain = 1.0
        f = fi.astype(np.float32)
        d = cv2.divide(f, estimate_background(f, width_px))
        np.subtract(np.float32(1.0), d, out=d)
        sub = d[::STRIDE, ::STRIDE].ravel()

    def threshold(level):
        return d.mask(level) if background is not None else \
            cv2.compare(d, float(level), cv2.CMP_GT)
    med = _median(sub)
    sigma = 1.4826 * _median(np.abs(sub - med))
    if not np.isfinite(sigma) or sigma <= 0:
        sigma = 1e-3
    seed = max(SEED_SIGMAS * sigma + med, min_contrast)
    H, W = d.shape
    if base_px is not None and 0 <= base_px[0] <= W - 1 and 0 <= base_px[1] <= H - 1:
        c = np.asarray(base_px, dtype=float)
        if base_dir is not None:
            c = c + 1.5 * width_px * np.asarray(base_dir, dtype=float)
        r = int(np.ceil(1.5 * width_px))
        u, v = int(round(c[0])), int(round(c[1]))
        win = d[max(v - r, 0):max(v + r + 1, 0), max(u - r, 0):max(u + r + 1, 0)]
        near = win[win > seed]
        if near.size >= 0.5 * width_px ** 2:
            contrast = _median(near)
            level = _level(contrast, med, sigma, min_contrast)
            return FlatField(d, threshold(level), float(level), float(contrast), float(sigma),
                             float(gain))
    seeds = sub[sub > seed]
    if seeds.size < 4:
        dd = np.asarray(d)
        seeds = dd[dd > seed]               # a short or thin catheter: look at every pixel
    if seeds.size < 8:
        mask = np.zeros(d.shape, np.uint8)
        return FlatField(d, mask, float('inf'), 0.0, sigma, gain, 'no_catheter')
    contrast = _median(seeds)
    level = _level(contrast, med, sigma, min_contrast)
    return FlatField(d, threshold(level), float(level), float(contrast), float(sigma),
                     float(gain))


def local_half_peak(mask: np.ndarray, score, width_px: float) -> Optional[np.ndarray]:
    """The mask (uint8 0/255) without the pixels darker than the threshold but not than half
    of the darkest pixel within half a catheter width: every object at its own
    half-maximum width. The catheter is unchanged (its core sets its own level, the
    threshold's), a thin line darker than the catheter (a lead wire: at the catheter's
    half contrast, blurred, it is segmented nearly as wide as the catheter) shrinks to its
    own width, which the sensor's opening and thin-run checks remove. Near a crossing the
    catheter's edge is cut within half a width of the darker line. None when nothing
    changes."""
    d = np.asarray(score, dtype=np.float32)
    r = max(1, int(round(0.5 * width_px)))
    peak = cv2.dilate(d, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1)))
    keep = cv2.compare(d, peak * np.float32(0.5), cv2.CMP_GT)
    out = cv2.bitwise_and(mask, keep)
    if cv2.countNonZero(cv2.bitwise_xor(out, mask)) == 0:
        return None
    return out
