"""A family of camera styles: a renderer with randomised parameters, for tests and benchmarks
of the shape sensor on images the project's own camera does not draw.

Each style differs in the physics of image formation, not only in noise:

==============  ===============================================================================
style           physics (ranges drawn per frame)
==============  ===============================================================================
``system``      the project's own `SyntheticCamera` (a catheter painted to a fixed dark grey,
                additive; vignetting 0-0.3; smooth texture; dark clamp jaw; electrodes;
                Gaussian noise 2-12; noise-free background frame)
``xray``        X-ray attenuation: the catheter MULTIPLIES the local light by its transmission
                (solid rod profile exp(-mu t(r)), core 0.25-0.5, a lighter lumen, near-opaque
                electrode rings); vignetting 30-45 % darker corners; the background frame at
                another exposure (the frame 0.5-1.5x as bright as the background frame); a dark
                clamp jaw touching the
                base; a tissue patch under the tip; signal-dependent (Poisson-Gaussian) noise
                3-8 grey levels; the background frame with its own noise
``anatomy``     attenuation as ``xray`` over an anatomical background: ribs (curved periodic
                dark bands), bright and dark vessel-like bands of about the catheter's width,
                a spine-like block; ECG lead wires (thin dark curves, 0.4-0.9 mm; in 30 %
                of frames one moved since the background frame); the background frame
                misregistered by up to 0.7 px (breathing)
``occluded``    an optical camera (the thesis's ex-vivo set-up): an opaque dark catheter
                (reflectance 0.08-0.25 of the local light); an introducer sheath or a clamp
                at the base; opaque tissue over the last 0-6 mm of the tip (70 % of frames);
                a tissue patch under the tip
``contrast``    attenuation from thin and faint (core transmission 0.6-0.85, up to 0.3 mm/px,
                i.e. an 8-pixel catheter) to saturated (exposure pushing 20-60 % of the
                background to 255 and the catheter core to 0)
``degraded``    attenuation or opaque, with motion blur of the catheter (3-10 px, any
                direction), JPEG compression (quality 25-75) of 8-bit frames, or 16-bit
                frames (12 significant bits)
``clinical``    low-dose fluoroscopy: attenuation over anatomy with a contrast-filled vessel
                (a dark band 2-5 mm wide) and a pacing lead, heart motion between the
                background frame and the frame (misregistration up to 1.5 px), noise 8-14
                grey levels, 16-bit frames in half of them, a sheath at the base
==============  ===============================================================================

`TUNING_STYLES` are the styles the sensor's defaults were developed and tuned on;
`HELD_OUT_STYLES` were never used for tuning and are reported separately by the benchmark.

Geometry is randomised per frame: image direction of the catheter (any angle), scale (per
style; enlarged when the shape would not fit) and the clamp position; a fraction of frames
is placed with the tip out of view (`StyledFrame.in_view` False) to test refusals. Ground
truth: `StyledFrame.truth_m`, the part of the centreline the sensor can see (from the base,
or from where the catheter enters the image, to the visible tip end).

Pure numpy/OpenCV; no rclpy.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import cv2
import numpy as np

from catheter_shape.camera import BLAZER_DIAMETER, SyntheticCamera, make_psi
from catheter_shape.scene import (SCALE as _SCALE, SHIFT as _SHIFT, anatomy, catheter_layers,
                                  clamp, expose, motion, patch, smooth_noise, vessel, wires)

__all__ = ['STYLES', 'TUNING_STYLES', 'HELD_OUT_STYLES', 'StyledFrame', 'render_style',
           'style_params']

STYLES = ('system', 'xray', 'anatomy', 'occluded', 'contrast', 'degraded', 'clinical')
#: styles the sensor's defaults were tuned on
TUNING_STYLES = ('system', 'xray', 'occluded', 'contrast')
#: styles never used for tuning (reported separately)
HELD_OUT_STYLES = ('anatomy', 'degraded', 'clinical')



@dataclass
class StyledFrame:
    """One frame of a style.

    image: uint8 or uint16 (H, W); background: the same scene without the catheter (same
    dtype; its own exposure and noise); psi (3, 4) and base_px (u, v): the calibration;
    centerline_m (k, 2): the whole catheter, m; truth_m (j, 2): what the sensor can see
    (clipped to the image, without the tip hidden under tissue); in_view: the whole tube
    lies in the image; hidden_tip: m of the tip under opaque tissue; style and params: what
    was drawn."""
    image: np.ndarray
    background: np.ndarray
    psi: np.ndarray
    base_px: tuple
    mm_per_px: float
    centerline_m: np.ndarray
    truth_m: np.ndarray
    in_view: bool
    hidden_tip: float
    style: str
    params: dict = field(default_factory=dict)


def _u(rng, lo, hi):
    return float(rng.uniform(lo, hi))


def style_params(style: str, rng: np.random.Generator) -> dict:
    """The randomised physical parameters of one frame of `style` (see the module table)."""
    if style not in STYLES:
        raise ValueError(f'style must be one of {STYLES}, got {style!r}')
    p = dict(style=style, model='transmissive', mm_per_px=_u(rng, 0.12, 0.2),
             transmission=_u(rng, 0.25, 0.5), lumen=_u(rng, 0.0, 0.3),
             electrode_transmission=_u(rng, 0.08, 0.3), vignetting=_u(rng, 0.0, 0.2),
             exposure=_u(rng, 0.85, 1.0), bg_exposure_ratio=1.0, level=_u(rng, 190, 225),
             noise=_u(rng, 3, 8), blur=_u(rng, 0.5, 1.1), motion=0.0, motion_angle=0.0,
             clamp='jaw' if rng.random() < 0.5 else 'none', tissue_under=False,
             tissue_over=0.0, anatomy=False, misregister=0.0, jpeg=0, bits=8,
             bg_frames=int(rng.choice([1, 4, 16])), black=_u(rng, 0, 6), vessel=False,
             partial=bool(rng.random() < 0.08), base_out=False)
    if style == 'system':
        p.update(model='system', noise=_u(rng, 2, 12), blur=_u(rng, 0.5, 1.2),
                 vignetting=_u(rng, 0.0, 0.3), clamp='jaw', base_out=bool(rng.random() < 0.1))
    elif style == 'xray':
        p.update(vignetting=_u(rng, 0.3, 0.45), exposure=_u(rng, 0.6, 1.0),
                 bg_exposure_ratio=float(np.exp(rng.uniform(np.log(0.5), np.log(1.5)))),
                 clamp='jaw', tissue_under=bool(rng.random() < 0.6), noise=_u(rng, 3, 8),
                 blur=_u(rng, 0.6, 1.2))
    elif style == 'anatomy':
        p.update(transmission=_u(rng, 0.3, 0.6), anatomy=True, vignetting=_u(rng, 0.1, 0.3),
                 misregister=_u(rng, 0.0, 0.7),
                 bg_exposure_ratio=_u(rng, 0.8, 1.2),
                 clamp='jaw' if rng.random() < 0.5 else 'sheath')
    elif style == 'occluded':
        p.update(model='opaque', reflectance=_u(rng, 0.08, 0.25), noise=_u(rng, 2, 6),
                 vignetting=_u(rng, 0.2, 0.4), clamp='sheath' if rng.random() < 0.5 else 'jaw',
                 tissue_under=bool(rng.random() < 0.5),
                 tissue_over=_u(rng, 0.0, 0.006) if rng.random() < 0.7 else 0.0)
    elif style == 'contrast':
        if rng.random() < 0.5:             # thin and faint
            p.update(transmission=_u(rng, 0.6, 0.85), mm_per_px=_u(rng, 0.15, 0.3),
                     noise=_u(rng, 2, 6), lumen=0.0)
        else:                              # saturated
            p.update(transmission=_u(rng, 0.03, 0.2), exposure=_u(rng, 1.15, 1.6),
                     noise=_u(rng, 2, 10))
    elif style == 'clinical':
        p.update(anatomy=True, vessel=True, misregister=_u(rng, 0.3, 1.5), noise=_u(rng, 8, 14),
                 transmission=_u(rng, 0.3, 0.55), vignetting=_u(rng, 0.2, 0.4),
                 clamp='sheath', bits=16 if rng.random() < 0.5 else 8,
                 bg_frames=int(rng.choice([4, 16])))
    elif style == 'degraded':
        if rng.random() < 0.3:
            p.update(model='opaque', reflectance=_u(rng, 0.08, 0.25))
        p.update(motion=_u(rng, 3, 10), motion_angle=_u(rng, 0, np.pi))
        if rng.random() < 0.5:
            p.update(jpeg=int(rng.integers(25, 76)))
        else:
            p.update(bits=16)
    return p


# --- geometry --------------------------------------------------------------------------------

def _frame_geometry(c: np.ndarray, p: dict, width: int, height: int, rng) -> tuple:
    """Scale, angle and clamp pixel so that the shape (and a margin) fits the image, or,
    for a `partial` frame, so that the tip leaves it. Returns (mm_per_px, angle, base_px)."""
    angle = _u(rng, -np.pi, np.pi)
    ca, sa = np.cos(angle), -np.sin(angle)
    ex, ey = np.array([ca, sa]), np.array([-np.sin(angle), -np.cos(angle)])
    rel = c[:, :1] * ex + c[:, 1:2] * ey                     # m per unit scale, in (u, v)
    # the clamp region behind the base stays in view too (8 mm)
    rel = np.vstack([rel, -0.008 * ex + 0.003 * ey, -0.008 * ex - 0.003 * ey])
    lo, hi = rel.min(axis=0), rel.max(axis=0)
    margin = 12.0 + 2.0 * BLAZER_DIAMETER * 1e3 / p['mm_per_px']
    span = (hi - lo) * 1e3                                  # mm
    need = max(span[0] / max(width - 2 * margin, 1), span[1] / max(height - 2 * margin, 1))
    mm = max(p['mm_per_px'], need)
    if mm > 0.4:                                            # too small to be useful: partial
        mm = p['mm_per_px']
    scale = 1e3 / mm
    box_lo, box_hi = lo * scale, hi * scale
    u0 = rng.uniform(margin - box_lo[0], max(margin - box_lo[0], width - margin - box_hi[0]))
    v0 = rng.uniform(margin - box_lo[1], max(margin - box_lo[1], height - margin - box_hi[1]))
    base = np.array([u0, v0])
    if p.get('partial'):
        # push the tip out of the image along the base -> tip direction
        tip = c[-1, 0] * ex + c[-1, 1] * ey
        d = tip / (np.linalg.norm(tip) + 1e-12)
        base = base + d * _u(rng, 0.15, 0.4) * np.linalg.norm(tip) * scale
    if p.get('base_out'):
        # move the clamp out of the image along -x: the catheter enters from the border
        d = -ex
        ts = [t for t in ((-base[0] / d[0]) if d[0] < 0 else (width - 1 - base[0]) / d[0]
                          if d[0] > 0 else np.inf,
                          (-base[1] / d[1]) if d[1] < 0 else (height - 1 - base[1]) / d[1]
                          if d[1] > 0 else np.inf)]
        base = base + d * (min(ts) + _u(rng, 5, 40))
    return mm, angle, (float(base[0]), float(base[1]))


def _visible(c_px: np.ndarray, c_m: np.ndarray, width: int, height: int, s_m: np.ndarray,
             hidden_tip: float) -> np.ndarray:
    """The longest run of centreline samples inside the image (from the base side) up to
    the start of the hidden tip."""
    inside = ((c_px[:, 0] >= 0) & (c_px[:, 0] <= width - 1) & (c_px[:, 1] >= 0)
              & (c_px[:, 1] <= height - 1) & (s_m <= s_m[-1] - hidden_tip + 1e-12))
    if not inside.any():
        return c_m[:0]
    idx = np.flatnonzero(inside)
    # first contiguous run
    br = np.flatnonzero(np.diff(idx) > 1)
    run = idx[:br[0] + 1] if br.size else idx
    return c_m[run]


def _render_system(c, p, width, height, rng, mm, angle, base):
    cam = SyntheticCamera(width=width, height=height, mm_per_px=mm, base_px=base, angle=angle,
                          noise=p['noise'], blur=p['blur'], vignetting=p['vignetting'],
                          seed=int(rng.integers(2 ** 31)))
    f = cam.render(c, rng=rng)
    return f.image, f.background


def render_style(style: str, centerline_m, rng: Optional[np.random.Generator] = None,
                 width: int = 640, height: int = 480, params: Optional[dict] = None,
                 diameter: float = BLAZER_DIAMETER) -> StyledFrame:
    """Draw a catheter with centreline (k, 2) m (catheter_base, base -> tip) in a frame of
    `style` with parameters drawn from `rng` (or the given `params`, from `style_params`).
    Returns a StyledFrame (image, background frame, calibration, truth)."""
    if style not in STYLES:
        raise ValueError(f'style must be one of {STYLES}, got {style!r}')
    c = np.asarray(centerline_m, dtype=float)
    if c.ndim != 2 or c.shape[1] not in (2, 3) or c.shape[0] < 2 or not np.isfinite(c).all():
        raise ValueError(f'centerline_m must be finite with shape (k>=2, 2|3), got {c.shape}')
    c = c[:, :2]
    rng = np.random.default_rng() if rng is None else rng
    p = dict(params) if params is not None else style_params(style, rng)
    mm, angle, base = _frame_geometry(c, p, width, height, rng)
    p.update(mm_per_px=mm, angle=angle, base_px=base)
    psi = make_psi(mm, base, angle)
    ppm = 1e3 / mm
    ex = np.array([np.cos(angle), -np.sin(angle)])
    ey = np.array([-np.sin(angle), -np.cos(angle)])
    px = np.asarray(base) + (c[:, :1] * ex + c[:, 1:2] * ey) * ppm
    s_m = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(c, axis=0), axis=1))])
    r_px = 0.5 * diameter * ppm
    H, W = height, width
    in_view = bool(px[:, 0].min() - r_px >= 0 and px[:, 1].min() - r_px >= 0
                   and px[:, 0].max() + r_px <= W - 1 and px[:, 1].max() + r_px <= H - 1)
    hidden = 0.0
    if p['model'] == 'system':
        image, background = _render_system(c, p, W, H, rng, mm, angle, base)
    else:
        v, u = np.mgrid[0:H, 0:W].astype(np.float32)
        r2 = ((u - W / 2) ** 2 + (v - H / 2) ** 2) / ((W / 2) ** 2 + (H / 2) ** 2)
        illum = (1.0 - np.float32(p['vignetting']) * r2) * np.float32(p['exposure'])
        scene = np.exp(smooth_noise(rng, H, W, 24, 0.04)).astype(np.float32)
        moved = None
        if p.get('vessel'):
            scene *= vessel(rng, H, W, mm)
        if p['anatomy']:
            scene *= anatomy(rng, H, W, mm)
            scene *= wires(rng, H, W, mm, int(rng.integers(1, 3)))
            if rng.random() < 0.3:
                moved = wires(rng, H, W, mm, 1)
        tip_px = px[-1]
        if p['tissue_under']:
            scene *= 1.0 - np.float32(_u(rng, 0.15, 0.35)) * patch(rng, H, W, tip_px, 0.012 * ppm)
        bmask = np.asarray(base)
        if p['clamp'] != 'none':
            cm = clamp(p['clamp'], bmask, ex, ey, ppm, H, W)
            dark = _u(rng, 0.1, 0.25) if p['clamp'] == 'jaw' else _u(rng, 0.35, 0.6)
            scene *= 1.0 - np.float32(1.0 - dark) * cm
        thick, elec = catheter_layers(px, s_m, r_px, H, W, p['lumen'])
        cover = np.clip(thick * 4.0, 0, 1)          # opaque model: coverage from the profile
        over = None
        if p['tissue_over'] > 0:
            depth = min(float(p['tissue_over']), 0.9 * s_m[-1])
            t = px[-1] - px[max(len(px) - 4, 0)]
            t = t / (np.linalg.norm(t) + 1e-12)
            R = 0.012 * ppm                              # a 12 mm tissue blob
            a_s = s_m[-1] - depth
            p_surf = np.array([np.interp(a_s, s_m, px[:, 0]), np.interp(a_s, s_m, px[:, 1])])
            centre = p_surf + R * t
            m = np.zeros((H, W), np.uint8)
            cv2.circle(m, tuple(int(x) for x in np.rint(centre * _SCALE)),
                       int(round(R * _SCALE)), 255, -1, cv2.LINE_AA, _SHIFT)
            over = m.astype(np.float32) / 255.0
            tex = (0.7 + 0.06 * np.sin(u * 0.21 + 0.5 * np.sin(v * 0.13)) * np.cos(v * 0.17))
            scene = scene * (1 - over) + over * tex.astype(np.float32)
            inside = np.linalg.norm(px - centre, axis=1) <= R
            first = int(np.argmax(inside)) if inside.any() else len(px) - 1
            hidden = float(s_m[-1] - s_m[first])
        if p['model'] == 'opaque':
            refl = np.float32(p['reflectance'])
            cath = 1.0 - cover * (1.0 - refl)
            cath *= 1.0 - elec * np.float32(0.5)
        else:
            mu = -np.log(p['transmission'])
            cath = np.exp(-np.float32(mu) * thick)
            cath *= 1.0 - elec * np.float32(1.0 - p['electrode_transmission'])
        if over is not None:
            cath = cath * (1 - over) + over
        if p['motion'] > 0:
            cath = motion(cath.astype(np.float32), p['motion'], p['motion_angle'])
        if p['clamp'] == 'sheath' and p['model'] == 'opaque':
            cm = clamp('sheath', bmask, ex, ey, ppm, H, W)
            cath = cath * (1 - cm) + cm
        light = illum * scene
        image = expose(light * cath * (1.0 if moved is None else moved), p,
                        p['bg_exposure_ratio'], rng)
        bg_light = light
        if p['misregister'] > 0:
            a = _u(rng, 0, 2 * np.pi)
            M = np.float32([[1, 0, p['misregister'] * np.cos(a)],
                            [0, 1, p['misregister'] * np.sin(a)]])
            bg_light = cv2.warpAffine(light, M, (W, H), flags=cv2.INTER_LINEAR,
                                      borderMode=cv2.BORDER_REFLECT)
        background = expose(bg_light, p, 1.0, rng, frames=p['bg_frames'])
    if p['model'] == 'system':
        # SyntheticCamera's tissue is not used here
        pass
    truth = _visible(px, c, W, H, s_m, hidden)
    return StyledFrame(image=image, background=background, psi=psi, base_px=base, mm_per_px=mm,
                       centerline_m=c, truth_m=truth, in_view=in_view, hidden_tip=hidden,
                       style=style, params=p)
