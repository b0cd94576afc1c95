"""Image-based shape sensing: camera frame to ordered centreline to Bezier control points; synthetic camera."""
