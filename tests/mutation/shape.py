"""Mutants of catheter_shape (camera frame -> centreline -> Bezier control points) for
tests/mutation/mutate.py: each breaks one property the package promises (the refined fit,
the clamped base, the plausibility checks that refuse a wrong shape, Eq. 1); the
catheter_shape tests (without the ROS node and README tests) must kill every one.

    python tests/mutation/mutate.py shape
"""
from mutate import Mutant

TESTS = ['tests/catheter_shape', '-k', 'not test_shape_node and not test_readme']

P = 'src/catheter_shape/catheter_shape/'

MUTANTS = [
    # -- issue 14's survivors
    Mutant('C01', P + 'sensor.py',
           "base_px=None, method: str = 'flatfield', degree: int = 3, refine: int = 1,",
           "base_px=None, method: str = 'flatfield', degree: int = 3, refine: int = 0,",
           'issue 14 survivor: the sensor runs the plain chord-length fit (refine=0), not the '
           'corrected one'),
    Mutant('C02', P + 'sensor.py',
           '        q1 = bp + 0.5 * gap * self._ex_px',
           '        q1 = 0.5 * (bp + q2)',
           'issue 14 survivor: the joint from the clamp is no longer tangent to the clamp (+x)'),
    # -- the Bezier fit (thesis Eqs. 2-5 with parameter correction)
    Mutant('C03', P + 'bezier.py',
           "    if correction == 'regularized' and refine > 0:",
           "    if False:",
           "the default 'regularized' correction silently runs the orthogonal one"),
    Mutant('C04', P + 'bezier.py',
           '        if e_t >= err:\n            if tw >= 1.0:',
           '        if e_t >= 10 * err:\n            if tw >= 1.0:',
           'orthogonal correction keeps steps that make the fit worse'),
    Mutant('C05', P + 'bezier.py',
           '    np.cumsum(d, out=s[1:])\n    s /= total',
           '    np.cumsum(d, out=s[1:])\n    s /= s.size',
           'Eq. 2: chord-length parameters not normalised to [0, 1]',
           tests=('tests/catheter_shape/test_bezier.py', '-k', 'chord_length')),  # else 280 s
    # -- Eq. 1 and the plausibility checks (refuse a wrong shape with a status)
    Mutant('C06', P + 'sensor.py',
           '        return uv @ self.psi[:, :2].T + self._origin',
           '        return uv @ self.psi[:, :2].T',
           'Eq. 1 without the calibration offset (control points shifted by the origin)'),
    Mutant('C07', P + 'sensor.py',
           '        if d.max() > self.max_fit_error:',
           '        if False:',
           "a curve that misses the centreline by millimetres is reported ok (no 'poor_fit')"),
    Mutant('C08', P + 'sensor.py',
           '            if length > L * (1.0 + self.length_tolerance):',
           '            if False:',
           "a centreline longer than the catheter is reported ok (no 'length_mismatch')"),
    Mutant('C09', P + 'sensor.py',
           '        elif gap > self.base_tolerance * w_px:',
           '        elif False:',
           "a catheter that starts away from the clamp is joined to it (no 'base_mismatch')"),
    Mutant('C10', P + 'sensor.py',
           '        if on_border(px[-1], shape, 0.5 * w_px + 1.0):',
           '        if False:',
           "a tip cut by the image border is reported as the tip ('tip_out_of_view' lost)"),
    Mutant('C11', P + 'sensor.py',
           '        if np.any((edge < 0.5 * w_px) & (s > 1.5 * w_px)):',
           '        if False:',
           'a catheter running along the image border (partly out of view) is reported ok'),
    Mutant('C12', P + 'sensor.py',
           '        if width > 2.5 * w_px or width < 0.3 * w_px:',
           '        if width > 25 * w_px:',
           "a dark object of the wrong width is taken for the catheter (no 'bad_segmentation')"),
    Mutant('C13', P + 'plausibility.py',
           "    if total >= np.pi and _crosses(q):\n        return 'the centreline crosses itself'",
           "    if False:\n        return 'the centreline crosses itself'",
           'a self-crossing centreline passes the fold check'),
    # -- issue 11 round three: the fast paths and the second pass
    Mutant('C14', P + 'flatfield.py',
           '            t = cv2.convertScaleAbs(self.background, alpha=k * self.gain, beta=0.4999)',
           '            t = cv2.convertScaleAbs(self.background, alpha=k * self.gain, beta=0.0)',
           'the integer mask rounds the threshold instead of taking its ceiling (pixels at '
           'the edge compared against the wrong level)',
           tests=('tests/catheter_shape/test_fast_paths.py',)),
    Mutant('C15', P + 'segmentation.py',
           '    x1 = min(int((st[:, cv2.CC_STAT_LEFT] + st[:, cv2.CC_STAT_WIDTH]).max()) + 1, w)',
           '    x1 = min(int((st[:, cv2.CC_STAT_LEFT] + st[:, cv2.CC_STAT_WIDTH]).max()) - 3, w)',
           'the component cropped short of its box (the catheter\'s end cut off)',
           tests=('tests/catheter_shape/test_fast_paths.py',)),
    Mutant('C16', P + 'sensor.py',
           "        if obs.status in RETRY_STATUSES and self.method == 'flatfield':",
           "        if False:",
           'no second pass at each pixel\'s own half maximum: a dark wire across the catheter '
           'fails the frame',
           tests=('tests/catheter_shape/test_fast_paths.py',)),
    Mutant('C17', P + 'flatfield.py',
           '    keep = cv2.compare(d, peak * np.float32(0.5), cv2.CMP_GT)',
           '    keep = cv2.compare(d, peak * np.float32(0.25), cv2.CMP_GT)',
           'the second pass holds each pixel to a quarter of its neighbourhood\'s darkness, '
           'not half (a dark wire keeps its blurred width)',
           tests=('tests/catheter_shape/test_fast_paths.py',)),
    # -- issue 15 round 9: the reused catheter/shape message, the camera's uint8 frame
    Mutant('C18', P + 'shape_node.py',
           '        msg.poses = pool[:p.shape[0]]',
           '        msg.poses = pool',
           'a path with fewer points than an earlier one keeps the earlier poses at its end',
           tests=('tests/catheter_shape/test_shape_node.py', '-k', 'reused')),
    Mutant('C19', P + 'shape_node.py',
           '            pos.x, pos.y, pos.z = x, y, z',
           '            pos.x, pos.y = x, y',
           'the refilled poses keep the previous frame\'s z',
           tests=('tests/catheter_shape/test_shape_node.py', '-k', 'reused')),
    Mutant('C20', P + 'camera.py',
           "        self._bg_half = self._bg - np.float32(0.5)",
           "        self._bg_half = self._bg",
           'the one-pass uint8 frame rounds bg + noise to nearest instead of truncating it'),
    Mutant('C21', P + 'camera.py',
           '            sub = bgb + noise[v0:v1, u0:u1] if noise is not None else bgb.copy()',
           '            sub = bgb.copy()',
           'the tube\'s box is composed without the noise the rest of the frame has'),
]
