"""Segmentation of a dark catheter: the thesis's thresholds on an 8-bit frame (section 2.4:
subtractive background removal and a greyscale threshold of 132; Otsu; adaptive), frame
conversion, cleanup and the catheter's connected component. The default, illumination-
independent method ('flatfield') lives in `catheter_shape.flatfield`.

Pure numpy/OpenCV; no rclpy. Frames are uint8 or uint16 (H, W); masks are uint8 0/255.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional, Tuple

import cv2
import numpy as np

__all__ = ['METHODS', 'FULL_SCALE', 'Segmentation', 'to_gray', 'to_uint8', 'threshold_frame',
           'catheter_component']

#: thresholding methods: 'flatfield' (the default: divisive flat-field, threshold at half the
#: catheter's own contrast; see catheter_shape.flatfield), 'fixed' (the thesis: grey <
#: threshold, after subtractive background removal when a background is given), 'otsu'
#: (global Otsu level), 'adaptive' (local mean minus an offset)
METHODS = ('flatfield', 'fixed', 'otsu', 'adaptive')
#: frame dtypes accepted, with their full scale
FULL_SCALE = {np.dtype(np.uint8): 255.0, np.dtype(np.uint16): 65535.0}


def to_gray(frame: np.ndarray) -> np.ndarray:
    """uint8/uint16 (H, W) or (H, W, 1) -> itself; (H, W, 3) BGR or (H, W, 4) BGRA -> grey
    (same dtype).

    Raises ValueError with the reason for any other array (the caller maps it to a status)."""
    if frame.dtype not in FULL_SCALE:
        raise ValueError(f'frame must be uint8 or uint16, got {frame.dtype} (convert, e.g. '
                         f'(frame * 255).astype(np.uint8) for floats in [0, 1])')
    if frame.size == 0:
        raise ValueError(f'frame is empty (shape {frame.shape})')
    if frame.ndim == 2:
        return frame
    if frame.ndim == 3 and frame.shape[2] == 1:
        return frame[:, :, 0]
    if frame.ndim == 3 and frame.shape[2] == 3:
        return cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
    if frame.ndim == 3 and frame.shape[2] == 4:
        return cv2.cvtColor(frame, cv2.COLOR_BGRA2GRAY)
    raise ValueError(f'frame must be (H, W), (H, W, 3) BGR or (H, W, 4) BGRA, got {frame.shape}')


def threshold_frame(gray: np.ndarray, threshold: int = 132,
                    background: Optional[np.ndarray] = None, method: str = 'fixed',
                    block: int = 51, offset: float = 25.0) -> Tuple[np.ndarray, np.ndarray, float]:
    """Binary mask of dark pixels.

    With a background (uint8, same shape), the frame is flat-fielded first:
    g = 255 - max(background - frame, 0), so the static scene becomes white, and 'fixed'
    keeps g < threshold (the catheter is at least 255 - threshold grey levels darker than
    the scene behind it). Without a background, 'fixed' keeps gray < threshold.
    'otsu' picks the level by Otsu's method on g; 'adaptive' keeps pixels darker than the
    local mean (block x block pixels, odd, at least 3: a coarse calibration can ask for
    less) minus `offset`.

    Returns (mask uint8 0/255, score uint8, level): score = 255 - g is the darkness image and
    mask == score > level (used for sub-pixel edge search; level is NaN for 'adaptive').
    """
    if background is not None:
        score = cv2.subtract(background, gray)          # saturating: max(bg - frame, 0)
    else:
        score = cv2.bitwise_not(gray)                   # 255 - gray
    if method == 'fixed':
        level = 255.0 - float(threshold)
        _, mask = cv2.threshold(score, level, 255, cv2.THRESH_BINARY)
    elif method == 'otsu':
        t, mask = cv2.threshold(score, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        level = float(t)
    elif method == 'adaptive':
        g = cv2.bitwise_not(score)
        mask = cv2.adaptiveThreshold(g, 255, cv2.ADAPTIVE_THRESH_MEAN_C, cv2.THRESH_BINARY_INV,
                                     max(3, int(block) | 1), float(offset))
        level = float('nan')
    else:
        raise ValueError(f'method must be one of {METHODS}, got {method!r}')
    return mask, score, level


#: a component is as thick as a catheter when its widest part is at least this fraction of
#: the catheter's width (thinner: a wire, a rim, a line of noise)
THICK = 0.6


def _thickness(blob: np.ndarray) -> float:
    """Width (pixels) of the widest part of a binary blob: twice its largest distance to
    the background."""
    m = cv2.copyMakeBorder(blob.astype(np.uint8), 1, 1, 1, 1, cv2.BORDER_CONSTANT, value=0)
    return 2.0 * float(cv2.distanceTransform(m, cv2.DIST_L2, 3).max())


def _elongated(xs: np.ndarray, ys: np.ndarray, min_length: float) -> bool:
    """A blob of pixels (xs, ys) is at least min_length long (sqrt(12 var) along its
    principal axis, the length of a uniform bar): a piece of catheter, not a roundish blob
    of texture or noise."""
    if xs.size < 3:
        return False
    c = np.cov(np.stack([xs, ys]).astype(float))
    lam = 0.5 * (c[0, 0] + c[1, 1]) + np.sqrt(0.25 * (c[0, 0] - c[1, 1]) ** 2 + c[0, 1] ** 2)
    return bool(np.sqrt(12.0 * lam) >= min_length)


def _component_at(labels, stats, order, bu, bv, reach, min_area):
    """The label of the component (area >= min_area) nearest to (bu, bv) in ROI pixels,
    within `reach` pixels; None if there is none."""
    best = None
    for k in order:
        if stats[k, cv2.CC_STAT_AREA] < min_area:
            break
        x, y, w, h = (int(stats[k, i]) for i in range(4))
        dx = max(x - bu, 0.0, bu - (x + w - 1))
        dy = max(y - bv, 0.0, bv - (y + h - 1))
        if np.hypot(dx, dy) > reach:
            continue
        r = int(np.ceil(reach))
        ys, xs = np.nonzero(labels[max(int(bv) - r, 0):int(bv) + r + 1,
                                   max(int(bu) - r, 0):int(bu) + r + 1] == k)
        if ys.size == 0:
            continue
        d = float(np.min(np.hypot(xs + max(int(bu) - r, 0) - bu, ys + max(int(bv) - r, 0) - bv)))
        if d <= reach and (best is None or d < best[0]):
            best = (d, int(k))
    return None if best is None else best[1]


@dataclass
class Segmentation:
    """The catheter's component: mask (uint8 0/1) of the region of interest at offset
    (u0, v0) of the full frame; area in pixels; n_objects = large components seen;
    bridged = gaps joined; apart = large catheter-thick objects left out because they do
    not touch the component at the clamp (only with `apart_ok`; the caller must decide
    whether the kept object is the whole catheter); status 'ok' or the reason it failed."""
    status: str
    mask: Optional[np.ndarray] = None
    offset: Tuple[int, int] = (0, 0)
    area: int = 0
    n_objects: int = 0
    bridged: int = 0
    message: str = ''
    apart: int = 0


def to_uint8(gray: np.ndarray) -> np.ndarray:
    """A grey frame as uint8 (uint16 keeps its 8 most significant bits)."""
    return gray if gray.dtype == np.uint8 else (gray >> 8).astype(np.uint8)


def catheter_component(mask: np.ndarray, min_area: float, max_gap_px: float,
                       width_px: float, second_ratio: float = 0.25,
                       max_fill: float = 0.5, base_px=None,
                       apart_ok: bool = False) -> Segmentation:
    """Clean a binary mask and keep the catheter: the component at the clamp pixel base_px
    (when given and inside the frame; else the largest) plus fragments within max_gap_px of
    it that are at least 1.5 widths long and as thick as a catheter (`THICK`; joined by the
    convex hull of both ends: gaps from occlusion or low contrast; a roundish blob or a
    wire near the tip is not joined); fails with 'multiple_objects' when another component
    as thick as a catheter and of at least second_ratio of the kept one's area remains (two
    catheters, or a piece of this one too far away), 'no_catheter'
    when the kept one is below min_area pixels, 'bad_segmentation' when more than max_fill
    of the frame is dark.

    apart_ok: when the kept component is the one at base_px (the clamp), a second object
    does not fail the frame: it is left out and counted in `apart` (a wire or a vessel that
    moved since the background frame is as dark as a catheter but does not touch the clamp);
    the caller refuses the frame unless the kept object is the whole catheter (its length)."""
    H, W = mask.shape
    u0, v0, w, h = cv2.boundingRect(mask)
    if w == 0 or h == 0:
        return Segmentation('no_catheter', message='nothing darker than the threshold')
    roi = mask[v0:v0 + h, u0:u0 + w]
    n_dark = cv2.countNonZero(roi)
    if n_dark > max_fill * H * W:
        return Segmentation('bad_segmentation',
                            message=f'{n_dark / (H * W):.0%} of the frame is below the threshold')
    # morphology: open removes noise pixels and structures thinner than a third of the
    # catheter (wires, rims of the background estimate), close fills pinholes
    k3 = np.ones((3, 3), np.uint8)
    if width_px >= 6:
        k = max(3, int(round(width_px / 3.0)) | 1)
        roi = cv2.morphologyEx(roi, cv2.MORPH_OPEN, np.ones((k, k), np.uint8))
        # the opening removed the noise pixels that stretched the box: go on in the box of
        # what is left, 2 pixels wider (the 3x3 closing then sees the same neighbourhood)
        a, b, w2, h2 = cv2.boundingRect(roi)
        if w2 == 0:
            return Segmentation('no_catheter', message='nothing left after cleanup')
        a0, b0 = max(a - 2, 0), max(b - 2, 0)
        a1, b1 = min(a + w2 + 2, w), min(b + h2 + 2, h)
        roi = roi[b0:b1, a0:a1]
        u0, v0, w, h = u0 + a0, v0 + b0, a1 - a0, b1 - b0
    roi = cv2.morphologyEx(roi, cv2.MORPH_CLOSE, k3)
    # 16-bit labels (half the labelling time) when no pattern of the box can have more
    # components than they count (8-connected: isolated pixels 2 apart)
    rh, rw = roi.shape
    ltype = cv2.CV_16U if ((rh + 1) // 2) * ((rw + 1) // 2) < 65535 else cv2.CV_32S
    n, labels, stats, _ = cv2.connectedComponentsWithStats(roi, connectivity=8, ltype=ltype)
    if n <= 1:
        return Segmentation('no_catheter', message='nothing left after cleanup')
    areas = stats[1:, cv2.CC_STAT_AREA]
    order = np.argsort(areas)[::-1] + 1
    main = int(order[0])
    at_base = False
    if base_px is not None and 0 <= base_px[0] <= W - 1 and 0 <= base_px[1] <= H - 1:
        near = _component_at(labels, stats, order, base_px[0] - u0, base_px[1] - v0,
                             2.0 * width_px, min_area)
        if near is not None:
            main = near
            at_base = True
            order = np.concatenate([[main], order[order != main]])
    if stats[main, cv2.CC_STAT_AREA] < min_area:
        return Segmentation('no_catheter', area=int(stats[main, cv2.CC_STAT_AREA]),
                            message=f'largest dark region has {stats[main, cv2.CC_STAT_AREA]} px'
                                    f' < {min_area:.0f}')
    keep = [main]
    bars = []
    apart = 0
    frag_min = max(4.0, 0.5 * width_px * width_px)
    for k in order[1:]:
        a = stats[k, cv2.CC_STAT_AREA]
        if a < frag_min:
            break
        # nearest pixels between the fragment and the kept region (in a window around it)
        x, y, fw, fh = (int(stats[k, i]) for i in range(4))
        g = int(np.ceil(max_gap_px)) + 1
        wx0, wy0 = max(x - g, 0), max(y - g, 0)
        wx1, wy1 = min(x + fw + g, w), min(y + fh + g, h)
        win = labels[wy0:wy1, wx0:wx1]
        fy, fx = np.nonzero(win == k)
        my, mx = np.nonzero(np.isin(win, keep))
        joined = False
        thick = None
        if my.size and fy.size and _elongated(fx, fy, 1.5 * width_px):
            thick = _thickness(win == k) >= THICK * width_px
        if thick:
            fs = max(1, fy.size // 400)
            ms = max(1, my.size // 400)
            F = np.stack([fx[::fs], fy[::fs]], 1).astype(np.float32)
            M = np.stack([mx[::ms], my[::ms]], 1).astype(np.float32)
            d2 = (np.sum(F * F, 1)[:, None] - 2 * F @ M.T + np.sum(M * M, 1)[None, :])
            i, j = np.unravel_index(int(np.argmin(d2)), d2.shape)
            if d2[i, j] <= max_gap_px ** 2:
                keep.append(int(k))
                # the bridge: the convex hull of both ends (the pixels within a width of the
                # nearest pair), so the gap is filled across the whole width of the tube
                r2 = (np.sqrt(d2[i, j]) + width_px) ** 2
                fe = F[np.sum((F - M[j]) ** 2, 1) <= r2]
                me = M[np.sum((M - F[i]) ** 2, 1) <= r2]
                hull = cv2.convexHull(np.vstack([fe, me]) + np.float32([wx0, wy0]))
                bars.append(np.rint(hull).astype(np.int32))
                joined = True
        if not joined and a >= second_ratio * stats[main, cv2.CC_STAT_AREA]:
            if thick is None:
                thick = _thickness(labels[y:y + fh, x:x + fw] == k) >= THICK * width_px
            if thick and apart_ok and at_base:
                apart += 1
            elif thick:         # a thin line (a wire) is not a second catheter
                return Segmentation('multiple_objects', n_objects=2,
                                    message=f'a second dark object of {a} px beside one of '
                                            f'{stats[main, cv2.CC_STAT_AREA]} px')
    # crop to the kept components (and a pixel of margin): the skeleton's cost grows with
    # the area it scans, and the dark pixels' bounding box can be much larger (clutter)
    st = stats[keep]
    x0 = max(int(st[:, cv2.CC_STAT_LEFT].min()) - 1, 0)
    y0 = max(int(st[:, cv2.CC_STAT_TOP].min()) - 1, 0)
    x1 = min(int((st[:, cv2.CC_STAT_LEFT] + st[:, cv2.CC_STAT_WIDTH]).max()) + 1, w)
    y1 = min(int((st[:, cv2.CC_STAT_TOP] + st[:, cv2.CC_STAT_HEIGHT]).max()) + 1, h)
    lab = labels[y0:y1, x0:x1]
    out = np.isin(lab, keep).astype(np.uint8) if len(keep) > 1 else \
        (lab == main).astype(np.uint8)
    for hull in bars:
        cv2.fillConvexPoly(out, hull - np.int32([x0, y0]), 1)
    return Segmentation('ok', mask=out, offset=(u0 + x0, v0 + y0), area=int(out.sum()),
                        n_objects=1 + apart, bridged=len(bars), apart=apart)
