"""Mutants of issue 15's round 9 (lockstep and the 1 kHz loops' CPU): the generated message
copies and CDR decoders, the worker bus's decoding of what it takes from DDS, one sim time for
every clock of a step, the nodes' integer clock read, the fast paths of catheter_common's
checks, and the recording writer's block reads (the recorder's fast Message path: B14-B18 in
bringup.py).

    python tests/mutation/mutate.py loops
"""
from mutate import Mutant

B = 'src/catheter_bringup/catheter_bringup/'
C = 'src/catheter_common/catheter_common/'
T = 'tests/catheter_bringup/'
COPY = (T + 'test_message_copy.py', '-k', 'not lockstep_with_copies')
TESTS = [T + 'test_message_copy.py', T + 'test_cdr_decode.py', T + 'test_realtime.py',
         T + 'test_rclpy_adapter.py', T + 'test_part_pipe.py',
         'tests/catheter_common/test_checks.py', 'tests/catheter_common/test_messages.py',
         'tests/catheter_common/test_clock_ns.py']

MUTANTS = [
    Mutant('L01', B + 'msg_copy.py',
           "if {v}.__class__ is not {name(\"_T\", exact)}:')",
           "if False and {v} is not {name(\"_T\", exact)}:')",
           'a scalar not of its field\'s exact type (an int in a double field) is copied',
           tests=COPY),
    Mutant('L02', B + 'msg_copy.py',
           "        lines.append(f'{indent}if {src}.__class__ is not {c}:')",
           "        lines.append(f'{indent}if False and {src} is not {c}:')",
           'a nested field holding another class is copied as if it were its type',
           tests=COPY),
    Mutant('L03', B + 'msg_copy.py',
           "                v = emit(conv.message_class, v, indent)",
           "                pass",
           'a nested message is shared with the original, not copied', tests=COPY),
    Mutant('L04', B + 'cdr_decode.py',
           "            g.lines.append(f'{ind}    p = (p + 7) & -8')",
           "            g.lines.append(f'{ind}    p = p')",
           'a float64[] is read without its 8-byte alignment',
           tests=(T + 'test_cdr_decode.py',)),
    Mutant('L05', B + 'cdr_decode.py',
           "                         '    if len(b) < 4 or b[0] != 0 or b[1] != 1:',",
           "                         '    if len(b) < 4 or b[0] != 0:',",
           'big-endian data is read as little endian', tests=(T + 'test_cdr_decode.py',)),
    Mutant('L06', B + 'cdr_decode.py',
           "    g.lines.append(f'{ind}p += 4 + {n}')",
           "    g.lines.append(f'{ind}p += 3 + {n}')",
           'the field after a string is read one byte early',
           tests=(T + 'test_cdr_decode.py',)),
    Mutant('L07', B + 'bus.py',
           '        if dec is not None:\n            set_raw(sub)\n',
           '',
           'a worker decodes what rclpy already deserialised (the subscription not raw)',
           tests=(T + 'test_realtime.py',)),
    Mutant('L08', B + 'bus.py',
           "        dec = decoder(sub.msg_type) if self.decode_dds and not sub.raw else None",
           "        dec = decoder(sub.msg_type) if not sub.raw else None",
           'decode_dds off is ignored', tests=(T + 'test_realtime.py',)),
    Mutant('L09', B + 'rclpy_adapter.py',
           '        ts._last_time_set = t\n',
           '',
           'a clock attached after a step does not start at the step\'s time',
           tests=(T + 'test_rclpy_adapter.py',)),
    Mutant('L10', C + 'ros_node.py',
           '            return _h.get_now().nanoseconds',
           '            return time.time_ns()',
           'clock_ns reads the system clock, not the node\'s (its sim time)',
           tests=('tests/catheter_common/test_clock_ns.py',)),
    Mutant('L11', C + 'checks.py',
           '    if value.__class__ is float and _isfinite(value):',
           '    if value.__class__ is float:',
           'finite() passes an infinite or NaN float',
           tests=('tests/catheter_common/test_checks.py',)),
    Mutant('L12', C + 'messages.py',
           '_model_getter = operator.attrgetter(*MODEL_FIELDS)',
           '_model_getter = operator.attrgetter(*MODEL_FIELDS[:-1])',
           'impedance_key ignores a model field (a changed model taken for the held one)',
           tests=('tests/catheter_common/test_messages.py',)),
    Mutant('L13', B + 'part_pipe.py',
           '                if n - start < length:\n                    break\n',
           '',
           'the writer takes a frame cut off at the end of the stream as a message',
           tests=(T + 'test_part_pipe.py',)),
    Mutant('L14', B + 'cdr.py',
           "p = ((p + {size - 1}) & {-size}) + {count} * {size}'",
           "p = p + {count} * {size}'",
           'the generated end skips the alignment of a sequence of doubles',
           tests=(T + 'test_cdr.py', '-k', 'generated_end')),
    Mutant('L15', B + 'cdr.py',
           "                                   '    return p if p <= n else None', ''])",
           "                                   '    return p', ''])",
           'the generated end of bytes cut short is taken as the message\'s end',
           tests=(T + 'test_cdr.py', '-k', 'generated_end')),
]
