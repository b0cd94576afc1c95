"""catheter_common.ros_node.clock_ns reads what Clock.now() reads, without building a Time."""
from rclpy.clock import Clock, ClockType, ROSClock
from rclpy.time import Time

from catheter_common.ros_node import clock_ns


def test_clock_ns_follows_a_ros_clocks_sim_time_override():
    c = ROSClock()
    now_ns = clock_ns(c)
    c._set_ros_time_is_active(True)
    for t in (0, 5, 1_000_000_001, 7_123_456_789):
        c.set_ros_time_override(Time(nanoseconds=t, clock_type=ClockType.ROS_TIME))
        assert now_ns() == t == c.now().nanoseconds
        assert type(now_ns()) is int


def test_clock_ns_of_the_system_clock_lies_between_two_now_calls():
    c = Clock(clock_type=ClockType.SYSTEM_TIME)
    now_ns = clock_ns(c)
    for _ in range(100):
        a = c.now().nanoseconds
        b = now_ns()
        assert a <= b <= c.now().nanoseconds
