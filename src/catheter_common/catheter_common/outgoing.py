"""Reused outgoing messages for the 1 kHz publishers: one message object per stream, its
stamp and values set in place before each publish, instead of building a Header, a Time, a
Wrench and two Vector3 (a WrenchStamped() costs ~20 us in CPython, a Time.to_msg() ~3 us).

Why this is safe: every publish path of the project serialises the message inside
``publish()`` (rclpy's DDS publish; the runner's ``LocalBus`` serialises before it queues,
and its subscribers get deserialised copies), so nothing holds the object after the call.
Code that intercepts a publisher and KEEPS what it is given must copy it (``copy.deepcopy``),
as with rclcpp's ``publish(const Msg &)``. Never hand a reused message to anything that
keeps it (a link queue, a cache).

Stamps are integer nanoseconds (``clock.now().nanoseconds``), split exactly as
``rclpy.time.Time.to_msg`` splits them, so the bytes on the wire are unchanged.
No rclpy: only the generated message classes.
"""
from __future__ import annotations

from catheter_interfaces.msg import MasterCommand
from geometry_msgs.msg import WrenchStamped

from catheter_common.checks import finite

_NS = 1_000_000_000


def set_stamp(stamp, ns: int) -> None:
    """Set a builtin_interfaces/Time in place from integer nanoseconds >= 0 (as
    ``Time(nanoseconds=ns).to_msg()``); ValueError naming `ns` otherwise."""
    if type(ns) is not int or ns < 0:      # bool and numpy ints refused too
        raise ValueError(f'ns must be integer nanoseconds >= 0, got {ns!r}')
    stamp.sec = ns // _NS
    stamp.nanosec = ns % _NS


class WrenchOut:
    """One WrenchStamped for a stream that carries force.x only (the rest stays 0)."""

    __slots__ = ('msg', '_stamp', '_force')

    def __init__(self, frame_id: str):
        if not isinstance(frame_id, str):
            raise ValueError(f'frame_id must be a string, got {frame_id!r}')
        self.msg = WrenchStamped()
        self.msg.header.frame_id = frame_id
        self._stamp = self.msg.header.stamp
        self._force = self.msg.wrench.force

    def fill(self, ns: int, fx: float) -> WrenchStamped:
        """The message stamped `ns` with force.x = `fx` (a float; not checked: the callers
        check their forces against their own limits)."""
        set_stamp(self._stamp, ns)
        self._force.x = fx
        return self.msg


class CommandOut:
    """One MasterCommand (catheter_common.messages.master_command_msg's fields and checks:
    ValueError naming the value that is not finite, the message left as it was)."""

    __slots__ = ('msg', '_stamp')

    def __init__(self, frame_id: str):
        if not isinstance(frame_id, str):
            raise ValueError(f'frame_id must be a string, got {frame_id!r}')
        self.msg = MasterCommand()
        self.msg.header.frame_id = frame_id
        self._stamp = self.msg.header.stamp

    def fill(self, ns: int, position: float, velocity: float, acceleration: float = 0.0,
             rotation: float = 0.0) -> MasterCommand:
        p = finite('position', position)
        v = finite('velocity', velocity)
        a = finite('acceleration', acceleration)
        r = finite('rotation', rotation)
        set_stamp(self._stamp, ns)
        m = self.msg
        m.position = p
        m.velocity = v
        m.acceleration = a
        m.rotation = r
        return m


__all__ = ['set_stamp', 'WrenchOut', 'CommandOut']
