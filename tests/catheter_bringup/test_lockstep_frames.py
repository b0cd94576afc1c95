"""The frames between the main and the vision process of a split lockstep run
(`catheter_bringup.lockstep_peer.frame` / `parse_frames`): a frame that arrived in part stays
in the buffer until the rest of it comes, whatever the cut."""
from catheter_bringup.lockstep_peer import MSG, STEP, frame, parse_frames


def test_frames_cut_anywhere_are_parsed_whole_once_complete():
    big = bytes(range(256)) * 40
    stream = frame(MSG, 7, (1, 2, 3), 4, big) + frame(STEP, 16) + frame(MSG, 8, (0, 0, 0), 1,
                                                                         b'xy')
    want = [(MSG, 7, (1, 2, 3), 4, big), (STEP, 16, (0, 0, 0), 0, b''),
            (MSG, 8, (0, 0, 0), 1, b'xy')]
    for cut in (1, 10, 25, 100, len(stream) - 30, len(stream) - 1):
        buf = bytearray(stream[:cut])
        got = parse_frames(buf)
        assert got == want[:len(got)]
        buf += stream[cut:]
        got += parse_frames(buf)
        assert got == want and buf == bytearray()
