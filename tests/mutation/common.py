"""Mutants of catheter_common (declared parameters, diagnostics, reused outgoing messages,
topic names, sensor_msgs/Image conversion) for tests/mutation/mutate.py: each breaks one
property the package promises; the catheter_common tests must kill every one.

    python tests/mutation/mutate.py common
"""
from mutate import Mutant

# the whole directory: 142 tests in about 12 s, the ROS-graph ones included (none is slow)
TESTS = ['tests/catheter_common']

P = 'src/catheter_common/catheter_common/'
T = 'tests/catheter_common/'

MUTANTS = [
    # -- params.py: declared parameters, validation, runtime changes
    Mutant('K01', P + 'params.py',
           '        if self.lo is not None and v < self.lo or self.hi is not None and v > '
           'self.hi:',
           '        if self.lo is not None and v <= self.lo or self.hi is not None and v >= '
           'self.hi:',
           'the inclusive range [lo, hi] refuses its own end points',
           tests=(T + 'test_params.py',)),
    Mutant('K02', P + 'params.py',
           '            if not all(math.isfinite(v) for v in out):',
           '            if False:',
           'a list of numbers with NaN or inf is accepted',
           tests=(T + 'test_params.py',)),
    Mutant('K03', P + 'params.py',
           '        d = ParameterDescriptor(description=self.description, '
           'read_only=not self.dynamic)',
           '        d = ParameterDescriptor(description=self.description, read_only=False)',
           'a start-only parameter is declared writable: a change is accepted and ignored',
           tests=(T + 'test_params.py',)),
    Mutant('K04', P + 'params.py',
           '            if value != self.values[prm.name]:',
           '            if True:',
           'setting a parameter to its current value runs the apply hook',
           tests=(T + 'test_params.py',)),
    Mutant('K05', P + 'params.py',
           '            if isinstance(value, bool) or not isinstance(value, int):',
           '            if not isinstance(value, int):',
           'an integer parameter accepts True / False (a bool is an int in Python)',
           tests=(T + 'test_params.py',)),
    Mutant('K06', P + 'params.py',
           "        when = 'runtime' if self.dynamic else 'start only'",
           "        when = 'start only' if self.dynamic else 'runtime'",
           '--help says a runtime parameter is start-only and the other way round',
           tests=(T + 'test_params.py',)),
    # -- diagnostics.py: levels, events, rate-limited logs, the published status
    Mutant('K07', P + 'diagnostics.py',
           '        items = sorted(act.items(), key=lambda kv: (-kv[1][0], kv[0]))',
           '        items = sorted(act.items(), key=lambda kv: (kv[1][0], kv[0]))',
           'the published level is the mildest active condition, not the worst',
           tests=(T + 'test_diagnostics.py',)),
    Mutant('K08', P + 'diagnostics.py',
           '            if t is not None and not (0 <= now - t < hold):',
           '            if t is not None and not (0 <= now - t <= hold):',
           'an event is still active exactly `hold` s after it was raised',
           tests=(T + 'test_diagnostics.py',)),
    Mutant('K09', P + 'diagnostics.py',
           '        if old is not None and old[2] is None and old[0] > level:\n            return',
           '        if False:\n            return',
           'an event of a lower level replaces a held condition of the same name (an ERROR '
           'becomes a WARN that clears by itself)',
           tests=(T + 'test_diagnostics.py',)),
    Mutant('K10', P + 'diagnostics.py',
           "        if slot is not None and t - slot[0] < self._log_period:",
           "        if slot is not None and t - slot[0] > self._log_period:",
           'bad inputs are logged every time instead of once per log_period',
           tests=(T + 'test_diagnostics.py',)),
    Mutant('K11', P + 'diagnostics.py',
           "                rate = (v - self._last_counts.get(k, 0)) / dt",
           "                rate = v / dt",
           'the published <counter>_rate_hz is the total over the last period, not the increase',
           tests=(T + 'test_diagnostics.py',)),
    # -- outgoing.py: reused messages for the 1 kHz publishers
    Mutant('K12', P + 'outgoing.py',
           '    stamp.nanosec = ns % _NS',
           '    stamp.nanosec = ns % 1_000_000',
           'the stamp\'s nanoseconds lose everything above a millisecond',
           tests=(T + 'test_outgoing.py',)),
    Mutant('K13', P + 'outgoing.py',
           "        r = finite('rotation', rotation)\n        set_stamp(self._stamp, ns)",
           "        set_stamp(self._stamp, ns)\n        r = finite('rotation', rotation)",
           'a refused rotation leaves the message with the new stamp (not as it was)',
           tests=(T + 'test_outgoing.py',)),
    Mutant('K14', P + 'outgoing.py',
           '    if type(ns) is not int or ns < 0:',
           '    if not isinstance(ns, int) or ns < 0:',
           'a bool is accepted as nanoseconds',
           tests=(T + 'test_outgoing.py',)),
    # -- topics.py: names and namespaces
    Mutant('K15', P + 'topics.py',
           "    if not isinstance(name, str) or not name.startswith('/') or len(name) < 2:",
           "    if not isinstance(name, str) or not name.startswith('/'):",
           "'/' is accepted as a topic name (relative gives '')",
           tests=(T + 'test_topics.py',)),
    Mutant('K16', P + 'topics.py',
           "    ns = namespace.rstrip('/')",
           "    ns = namespace",
           "a namespace with a trailing '/' (and the root '/') gives '//' in the name",
           tests=(T + 'test_topics.py',)),
    Mutant('K17', P + 'topics.py',
           "'/rosout', '/parameter_events', '/tf', '/tf_static'})",
           "'/rosout', '/parameter_events', '/tf_static'})",
           '/tf moves into the namespace where ROS tools do not look for it',
           tests=(T + 'test_topics.py',)),
    # -- images.py: sensor_msgs/Image <-> numpy
    Mutant('K18', P + 'images.py',
           '    if step < w * ch:',
           '    if step < w:',
           'a step shorter than a row of a colour image is not refused by name (a numpy '
           'reshape error instead)',
           tests=(T + 'test_images.py',)),
    Mutant('K19', P + 'images.py',
           "        return a[:, :, [2, 1, 0, 3]]",
           "        return a[:, :, [0, 1, 2, 3]]",
           'rgba8 comes back in RGBA order, not BGRA',
           tests=(T + 'test_images.py',)),
    Mutant('K20', P + 'images.py',
           '    if h <= 0 or w <= 0:',
           '    if h < 0 or w < 0:',
           'an empty (0-row or 0-column) image decodes to an empty array instead of being '
           'refused',
           tests=(T + 'test_images.py',)),
    Mutant('K21', P + 'images.py',
           "    msg.step = msg.width * ch",
           "    msg.step = msg.width",
           'a bgr8 message says a row is width bytes long, not 3 x width',
           tests=(T + 'test_images.py',)),
]
