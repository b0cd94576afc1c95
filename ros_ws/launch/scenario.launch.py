"""Launch a scenario of ros_ws/config/ as separate processes (needs a full ROS 2 install with
`launch` and `launch_ros`; the PyPI wheels this project installs have neither, so here use the
launchless runner `run_scenario`, which also offers lockstep on a simulated clock):

    ros2 launch ros_ws/launch/scenario.launch.py scenario:=experiment_ii

The nodes, parameters and remappings come from the same YAML and resolution as the launchless
runner (catheter_bringup.make_launch.launch_entries), plus a recorder writing bags/<name>.mcap.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context, *args, **kwargs):
    from catheter_bringup.make_launch import launch_entries
    from catheter_bringup.scenario import load_scenario
    scenario = load_scenario(LaunchConfiguration('scenario').perform(context))
    return [Node(output='screen', **entry) for entry in launch_entries(scenario)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='experiment_ii',
                              description='name of a scenario YAML in ros_ws/config/'),
        OpaqueFunction(function=_nodes),
    ])
