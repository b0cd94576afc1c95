"""The catheter's component: chosen at the clamp, thin structures and roundish blobs are not
the catheter, gaps along it are bridged; clutter does not set the flat-field level."""
import cv2
import numpy as np

from catheter_shape.flatfield import flat_field, prepare_background
from catheter_shape.segmentation import catheter_component


def _bar(mask, p, q, width):
    cv2.line(mask, p, q, 255, width)


def test_thin_wires_are_opened_away():
    """A 3 px wire (an ECG lead) across a 15 px catheter: not part of the catheter's
    component."""
    m = np.zeros((200, 400), np.uint8)
    _bar(m, (20, 100), (300, 100), 15)
    alone = catheter_component(m.copy(), 50, 20, 15.0)
    _bar(m, (150, 0), (180, 199), 2)
    seg = catheter_component(m, 50, 20, 15.0)
    assert seg.status == 'ok'
    assert abs(seg.area - alone.area) < 0.02 * alone.area


def test_a_round_blob_beyond_the_tip_is_not_joined_an_aligned_piece_is():
    m = np.zeros((200, 400), np.uint8)
    _bar(m, (20, 100), (250, 100), 15)
    cv2.circle(m, (272, 100), 7, 255, -1)               # 15 px blob 15 px beyond the end
    seg = catheter_component(m.copy(), 50, 20, 15.0)
    assert seg.status == 'ok' and seg.bridged == 0
    m2 = np.zeros((200, 400), np.uint8)
    _bar(m2, (20, 100), (250, 100), 15)
    _bar(m2, (278, 100), (310, 100), 15)                # a piece after a 14 px gap
    seg = catheter_component(m2, 50, 20, 15.0)
    assert seg.status == 'ok' and seg.bridged == 1


def test_the_component_at_the_clamp_wins_over_a_larger_one():
    m = np.zeros((300, 400), np.uint8)
    _bar(m, (20, 50), (200, 50), 15)                    # the catheter at the clamp (20, 50)
    cv2.rectangle(m, (100, 150), (380, 290), 255, -1)   # a larger dark region far away
    seg = catheter_component(m, 50, 20, 15.0, second_ratio=1e9, max_fill=0.9,
                             base_px=(20.0, 50.0))
    assert seg.status == 'ok' and seg.area < 4000


def test_clutter_far_from_the_clamp_does_not_pull_the_level_down():
    """Many small, slightly dark dots (texture) and one dark catheter, no background frame:
    measured at the clamp, the contrast is the catheter's; from the whole frame's clutter
    it would be the dots'."""
    rng = np.random.default_rng(0)
    img = np.full((300, 400), 200.0, np.float32)
    for _ in range(150):
        c = (int(rng.integers(0, 400)), int(rng.integers(0, 300)))
        cv2.circle(img, c, 6, 170.0, -1)                # 15 % darker dots
    cv2.line(img, (30, 150), (330, 150), 40.0, 15)      # the catheter, 80 % darker
    img = cv2.GaussianBlur(img, (0, 0), 1.0).astype(np.uint8)
    at_clamp = flat_field(img, None, 15.0, base_px=(30.0, 150.0), base_dir=(1.0, 0.0))
    anywhere = flat_field(img, None, 15.0)
    assert at_clamp.contrast > 0.5 and at_clamp.level > 0.25
    assert anywhere.contrast < 0.3                      # what the clamp window avoids
    assert not at_clamp.mask[:135].any() and not at_clamp.mask[166:].any()


def test_flat_field_with_a_background_sees_only_the_catheter():
    rng = np.random.default_rng(1)
    bg = np.clip(150 + 40 * np.sin(np.arange(400) / 30.0)[None, :]
                 + 2 * rng.standard_normal((300, 400)), 0, 255).astype(np.uint8)
    img = bg.astype(np.float32)
    img[140:160, 50:350] *= 0.4                          # 60 % attenuation
    img = np.clip(img + 2 * rng.standard_normal(img.shape), 0, 255).astype(np.uint8)
    ff = flat_field(img, prepare_background(bg, 20.0), 20.0, base_px=(50.0, 150.0),
                    base_dir=(1.0, 0.0))
    assert 0.45 < ff.contrast < 0.65          # the median over the blurred profile
    rows = np.nonzero(ff.mask[:, 200])[0]
    assert rows.min() in (139, 140, 141) and rows.max() in (158, 159, 160)


def test_a_long_wire_elsewhere_is_not_a_second_catheter():
    """A 6 px wire (an ECG lead, 0.4 catheter widths) away from the catheter, as large as a
    third of it: not 'multiple_objects'; a second 15 px tube is."""
    m = np.zeros((300, 500), np.uint8)
    _bar(m, (20, 60), (300, 60), 15)
    wire = m.copy()
    _bar(wire, (20, 200), (480, 230), 5)
    seg = catheter_component(wire, 50, 20, 15.0, base_px=(20.0, 60.0))
    assert seg.status == 'ok' and seg.area < 5000
    _bar(m, (20, 200), (300, 230), 15)
    assert catheter_component(m, 50, 20, 15.0, base_px=(20.0, 60.0)).status == 'multiple_objects'
