"""sensor_msgs/Image <-> numpy, the one implementation every node uses (the camera publishes
with it, the shape node decodes and publishes its overlay with it).

Encodings: mono8 / 8UC1 (H, W), bgr8 / rgb8 / 8UC3 (H, W, 3), bgra8 / rgba8 (H, W, 4);
arrays are returned in BGR(A) channel order. Bad messages raise ValueError saying what is
wrong (unsupported encoding, empty, step shorter than a row, too little data).
"""
from __future__ import annotations

import numpy as np
from sensor_msgs.msg import Image

#: channels of each supported 8-bit encoding
CHANNELS = {'mono8': 1, '8UC1': 1, 'bgr8': 3, 'rgb8': 3, 'bgra8': 4, 'rgba8': 4, '8UC3': 3}
#: largest accepted height or width, px (a bigger header is refused before any allocation)
MAX_SIDE = 1 << 15


def image_to_array(msg: Image) -> np.ndarray:
    """sensor_msgs/Image -> uint8 array (H, W) grey or (H, W, 3|4) in BGR(A) order (a view of
    the message's data where possible). ValueError for what cannot be decoded."""
    enc = msg.encoding
    if enc not in CHANNELS:
        raise ValueError(f'unsupported image encoding {enc!r} '
                         f'(supported: {", ".join(CHANNELS)})')
    ch = CHANNELS[enc]
    h, w, step = int(msg.height), int(msg.width), int(msg.step)
    if h <= 0 or w <= 0:
        raise ValueError(f'empty image {w}x{h}')
    if h > MAX_SIDE or w > MAX_SIDE:
        raise ValueError(f'image {w}x{h} larger than {MAX_SIDE} px on a side')
    if step < w * ch:
        raise ValueError(f'step {step} < width {w} x {ch} channels')
    try:
        buf = np.frombuffer(msg.data, dtype=np.uint8)        # array.array / bytes: no copy
    except (TypeError, ValueError):
        buf = np.frombuffer(bytes(msg.data), dtype=np.uint8)
    if buf.size < h * step:
        raise ValueError(f'image data has {buf.size} bytes, expected {h * step} '
                         f'({h} rows of {step})')
    a = buf[:h * step].reshape(h, step)[:, :w * ch]
    if ch == 1:
        return a
    a = a.reshape(h, w, ch)
    if enc == 'rgb8':
        return a[:, :, ::-1]
    if enc == 'rgba8':
        return a[:, :, [2, 1, 0, 3]]
    return a


def array_to_image(a: np.ndarray, stamp, frame_id: str) -> Image:
    """uint8 (H, W) -> mono8, (H, W, 3) -> bgr8 sensor_msgs/Image with the given stamp and
    frame. ValueError for other shapes or dtypes."""
    a = np.asarray(a)
    if a.dtype != np.uint8 or a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3) \
            or a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f'image array must be uint8 (H, W) or (H, W, 3), got {a.dtype} '
                         f'{a.shape}')
    msg = Image()
    msg.header.stamp = stamp
    msg.header.frame_id = frame_id
    msg.height, msg.width = int(a.shape[0]), int(a.shape[1])
    msg.encoding, ch = ('mono8', 1) if a.ndim == 2 else ('bgr8', 3)
    msg.is_bigendian = 0
    msg.step = msg.width * ch
    msg.data = np.ascontiguousarray(a).tobytes()
    return msg
