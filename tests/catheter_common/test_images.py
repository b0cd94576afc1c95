"""catheter_common.images: sensor_msgs/Image <-> numpy, and any malformed message is a
ValueError saying what is wrong (hypothesis over headers and data sizes)."""
import numpy as np
import pytest
from builtin_interfaces.msg import Time
from hypothesis import given
from hypothesis import strategies as st
from sensor_msgs.msg import Image

from catheter_common.images import CHANNELS, array_to_image, image_to_array


def test_round_trip_mono_and_bgr():
    rng = np.random.default_rng(0)
    for shape in ((5, 7), (4, 6, 3)):
        a = rng.integers(0, 256, shape, dtype=np.uint8)
        msg = array_to_image(a, Time(sec=3), 'cam')
        assert msg.header.frame_id == 'cam' and msg.header.stamp.sec == 3
        assert msg.encoding == ('mono8' if a.ndim == 2 else 'bgr8')
        assert msg.step == a.shape[1] * (1 if a.ndim == 2 else 3)
        np.testing.assert_array_equal(image_to_array(msg), a)


def test_rgb_and_padding_rows():
    a = np.arange(2 * 3 * 3, dtype=np.uint8).reshape(2, 3, 3)
    msg = Image(height=2, width=3, encoding='rgb8', step=12)
    rows = [np.r_[a[r].reshape(-1), [0, 0, 0]] for r in range(2)]
    msg.data = np.concatenate(rows).astype(np.uint8).tobytes()
    np.testing.assert_array_equal(image_to_array(msg), a[:, :, ::-1])


def test_bad_arrays_refused():
    for a in (np.zeros((2, 2), np.float32), np.zeros((2, 2, 4), np.uint8),
              np.zeros((0, 3), np.uint8), np.zeros(5, np.uint8)):
        with pytest.raises(ValueError, match='image array'):
            array_to_image(a, Time(), 'x')


@given(h=st.integers(-2, 40), w=st.integers(-2, 40), step=st.integers(-2, 200),
       enc=st.sampled_from(sorted(CHANNELS) + ['32FC1', '', 'mono16', 'bayer']),
       n=st.integers(0, 4000))
def test_any_header_decodes_consistently_or_is_refused(h, w, step, enc, n):
    msg = Image()
    msg.height, msg.width = max(h, 0), max(w, 0)
    msg.step = max(step, 0)
    msg.encoding = enc
    msg.data = bytes(n % 256 for n in range(n))
    try:
        a = image_to_array(msg)
    except ValueError as exc:
        assert str(exc)
        return
    ch = CHANNELS[enc]
    assert a.dtype == np.uint8 and a.shape[:2] == (msg.height, msg.width)
    assert (a.ndim == 2) == (ch == 1) and msg.step * msg.height <= n
