"""Every rclpy internal the runner relies on, in one place (rclpy 7.1, ROS 2 Jazzy).

The lockstep runner drives the nodes itself: it intercepts what they publish, delivers
messages to their subscription callbacks, sets their sim time and fires their timers,
without DDS and without an executor's wait set per callback. That needs behaviour rclpy
does not promise; each function here names what it relies on, and
tests/catheter_bringup/test_rclpy_adapter.py pins every one of them, so a new rclpy fails
one clear test instead of changing a run silently. `check_rclpy()` says whether the
installed rclpy is a tested one.

Nothing else in the project reaches into rclpy's private attributes.
"""
from __future__ import annotations

from typing import Callable, Optional, Tuple

#: rclpy versions (major.minor) whose internals the functions below were checked against
TESTED_RCLPY = ('7.1',)


def rclpy_version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    for dist in ('ros-jazzy-rclpy', 'rclpy'):
        try:
            return version(dist)
        except PackageNotFoundError:
            continue
    return 'unknown'


def check_rclpy() -> Tuple[bool, str]:
    """(tested, version): whether the installed rclpy is one this module was checked on."""
    v = rclpy_version()
    return '.'.join(v.split('.')[:2]) in TESTED_RCLPY, v


# ------------------------------------------------------------------ publishers
def intercept_publish(pub, fn: Callable) -> Callable:
    """Make ``pub.publish(msg)`` call ``fn(msg)`` instead; returns the original bound
    ``publish`` (``fn`` may call it to publish on DDS too).

    Relies on: Publisher has no __slots__, so an instance attribute shadows the method, and
    the nodes call ``self.pub.publish(msg)`` (attribute lookup at each call)."""
    orig = pub.publish
    pub.publish = fn
    return orig


def count_extra_subscriber(pub) -> None:
    """Make ``pub.get_subscription_count()`` count one subscriber more than DDS knows of (a
    recorder that takes the messages in the publishing process: nodes that work only while
    subscribed keep publishing for it).

    Relies on: as `intercept_publish`, an instance attribute shadows the method."""
    orig = pub.get_subscription_count
    pub.get_subscription_count = lambda _orig=orig: _orig() + 1


# ------------------------------------------------------------------ subscriptions
def callback_wants_info(sub) -> bool:
    """True if the subscription's callback takes (msg, message_info).

    Relies on: the private ``Subscription._callback_type`` (an enum whose MessageOnly member
    means callback(msg))."""
    ct = getattr(sub, '_callback_type', None)
    return ct is not None and ct.name != 'MessageOnly'


def take_callback(sub, replacement: Callable, raw: bool = False) -> Tuple[Callable, bool]:
    """Replace the subscription's callback; returns (the old callback, whether it takes
    message info). What DDS still delivers to the subscription goes to `replacement`; with
    ``raw=True`` as bytes (taken without deserialising: cheap to drop).

    Relies on: the executor calls ``sub.callback`` (a plain attribute) for each message, and
    reads ``sub.raw`` at each take (SingleThreadedExecutor and EventsExecutor alike)."""
    old = sub.callback
    wants = callback_wants_info(sub)
    sub.callback = replacement
    if raw:
        sub.raw = True
    return old, wants


def set_raw(sub) -> None:
    """Make the executor take the subscription's messages as their CDR bytes (its callback
    then gets bytes instead of a message).

    Relies on: as `take_callback`, the executor reads ``sub.raw`` at each take."""
    sub.raw = True


def wrap_callback(sub, wrapper: Callable[[Callable], Callable]) -> None:
    """``sub.callback = wrapper(sub.callback)`` (e.g. to count what it took), keeping what the
    executor hands it: a callback that takes (msg, message_info) still gets the info.

    Relies on: rclpy decides at each assignment of ``sub.callback`` from the callable's
    signature whether it takes message info (a ``*args`` wrapper would be taken for
    message-only), so the wrapper is assigned with the original's arity."""
    wants = callback_wants_info(sub)
    inner = wrapper(sub.callback)
    if wants:
        sub.callback = lambda msg, info, _f=inner: _f(msg, info)
    else:
        sub.callback = lambda msg, _f=inner: _f(msg)


def watch_message_lost(node, sub, callback: Callable[[int], None]) -> None:
    """Call ``callback(total)`` whenever DDS reports samples of subscription `sub` lost (total:
    since it was created) - added after the subscription was made by its node. DDS reports a
    gap in the sequence numbers the reader received: samples lost in transport or never sent
    by the writer. A sample the subscription's own queue (KEEP_LAST depth) dropped because it
    was not taken in time is not reported.

    Relies on: ``SubscriptionEventCallbacks.create_event_handlers(callback_group, handle,
    topic)`` building the handlers ``Node.create_subscription`` adds for ``event_callbacks``;
    ``sub.event_handlers`` being the list ``Node.destroy_subscription`` removes and destroys;
    ``node.add_waitable`` handing them to the node's executor (the EventsExecutor too)."""
    from rclpy.event_handler import SubscriptionEventCallbacks
    cbs = SubscriptionEventCallbacks(
        message_lost=lambda status: callback(int(status.total_count)),
        use_default_callbacks=False)
    handlers = cbs.create_event_handlers(sub.callback_group, sub.handle, sub.topic_name)
    sub.event_handlers.extend(handlers)
    for h in handlers:
        node.add_waitable(h)


# ------------------------------------------------------------------ time
def detach_clock(node):
    """Take the node's sim time away from /clock: destroys the TimeSource's /clock
    subscription and returns the TimeSource (None if the node has none), whose time
    `set_time` then sets.

    Relies on: the private ``Node._time_source`` and ``TimeSource._clock_sub`` (the /clock
    subscription, created when use_sim_time is true)."""
    ts = getattr(node, '_time_source', None)
    if ts is None:
        return None
    if ts._clock_sub is not None:
        node.destroy_subscription(ts._clock_sub)
        ts._clock_sub = None
    return ts


def set_time(ts, clock_msg) -> None:
    """Set the sim time of every clock of the TimeSource (as a /clock message would).

    Relies on: ``TimeSource.clock_callback(msg)`` setting the ROS time override of its clocks
    (and thereby making due timers ready)."""
    ts.clock_callback(clock_msg)


def set_times(sources, t_ns: int) -> None:
    """Set the sim time of every clock of every TimeSource in `sources` to `t_ns` (int ns), as
    `set_time` with a /clock message of that time would, with one rclpy Time for all of them
    (`set_time` builds one per TimeSource from the message: a lockstep step sets every
    node's time).

    Relies on: what ``TimeSource.clock_callback`` does: keep the time in ``_last_time_set``
    (a clock attached later starts there) and ``set_ros_time_override`` it on each clock of
    ``_associated_clocks``."""
    from rclpy.clock_type import ClockType
    from rclpy.time import Time
    t = Time(nanoseconds=t_ns, clock_type=ClockType.ROS_TIME)
    for ts in sources:
        ts._last_time_set = t
        for clock in ts._associated_clocks:
            clock.set_ros_time_override(t)


# ------------------------------------------------------------------ timers
def timer_ready(tmr) -> Optional[bool]:
    """Whether the timer is due; None when it has been destroyed."""
    try:
        return tmr.is_ready()
    except Exception:  # noqa: BLE001 - a destroyed timer's handle raises
        return None


def timer_due_in_ns(tmr) -> Optional[int]:
    """ns until the timer is due (<= 0: due); None when destroyed or canceled."""
    try:
        return tmr.time_until_next_call()
    except Exception:  # noqa: BLE001 - a destroyed timer's handle raises
        return None


def wrap_timer_callback(tmr, wrapper: Callable[[Callable], Callable]) -> None:
    """``tmr.callback = wrapper(tmr.callback)`` (e.g. to time it).

    Relies on: every executor (EventsExecutor too) calls ``Timer.callback`` (a plain
    attribute) when the timer is due."""
    tmr.callback = wrapper(tmr.callback)


def fire_timer(tmr) -> None:
    """Run a due timer's callback as the executor would: mark the period as called (the next
    one is due a period later), then call the callback.

    Relies on: ``Timer.handle.call_timer()`` (the C timer's "call", which advances it to
    its next period, done under the handle's context manager) and ``Timer.callback``."""
    with tmr.handle:
        tmr.handle.call_timer()
    tmr.callback()


# ------------------------------------------------------------------ executors
def spin_ready(executor, limit: int, timeout: float = 0.0) -> int:
    """Run up to `limit` callbacks that are ready (the first wait up to `timeout` s, the rest
    without waiting); an exception raised in a callback is raised here. Returns how many ran.

    The one spin helper of the runner. Relies on: ``Executor.wait_for_ready_callbacks``
    returning (handler, entity, node) and raising TimeoutException when nothing is ready,
    and the handler keeping a callback's exception (``handler.exception()``) instead of
    raising it."""
    from rclpy.executors import TimeoutException
    n = 0
    wait = timeout
    while n < limit:
        try:
            handler, _, _ = executor.wait_for_ready_callbacks(timeout_sec=wait)
        except TimeoutException:
            break
        wait = 0.0
        handler()
        exc = handler.exception()
        if exc is not None:
            raise exc
        n += 1
    return n


def shutdown_context(context) -> None:
    """Shut down an rclpy context the runner created (no error if it is already down)."""
    import rclpy
    rclpy.try_shutdown(context=context)


def never_done():
    """A future nobody completes, for `spin_for` (one per run loop)."""
    from rclpy.task import Future
    return Future()


def spin_for(executor, timeout: float, never) -> None:
    """Let the executor run its own loop for `timeout` s (EventsExecutor: its C++ loop, no
    Python turn per event): ``spin_until_future_complete`` on `never` (`never_done()`); an
    executor without it gets one ``spin_once``."""
    spin = getattr(executor, 'spin_until_future_complete', None)
    if spin is None:
        executor.spin_once(timeout_sec=timeout)
    else:
        spin(never, timeout_sec=timeout)


# ------------------------------------------------------------------ serialisation, arguments
_SERIALIZER: Optional[Tuple[Callable, Callable]] = None


def serializer() -> Tuple[Callable, Callable]:
    """(serialize_message, deserialize_message) of rclpy (the bus's transport). Imported once:
    the bus asks at every delivery round (in a worker, after every timer callback)."""
    global _SERIALIZER
    if _SERIALIZER is None:
        from rclpy.serialization import deserialize_message, serialize_message
        _SERIALIZER = (serialize_message, deserialize_message)
    return _SERIALIZER


def without_ros_args(argv) -> list:
    """A command line without its ROS arguments (``--ros-args ... --``), as ros2 run passes
    them; argv[0] is not a program name here."""
    from rclpy.utilities import remove_ros_args
    return remove_ros_args(['x'] + list(argv))[1:]
