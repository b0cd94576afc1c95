"""Launch a scenario (a YAML file of catheter_bringup's config/, installed to
share/catheter_bringup/config) as separate processes, on a ROS 2 install with `launch` and
`launch_ros`:

    ros2 launch catheter_bringup scenario.launch.py scenario:=experiment_ii
    ros2 launch catheter_bringup scenario.launch.py scenario:=experiment_ii layout:=split

The PyPI wheels this project installs have neither `launch` nor `ros2launch`: here use the
launchless runner `run_scenario`, which also offers lockstep on a simulated clock.

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
    layout = LaunchConfiguration('layout').perform(context)
    if layout:
        from catheter_bringup.overrides import apply_overrides
        scenario = apply_overrides(scenario, ['mode=realtime', f'layout={layout}'])
    return [Node(output='screen', **entry) for entry in launch_entries(scenario)]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scenario', default_value='experiment_ii',
                              description="a scenario name of catheter_bringup's config/ "
                                          'or a path to a YAML file'),
        DeclareLaunchArgument('layout', default_value='',
                              description="'split': master, slave and vision processes over "
                                          "DDS (the deployment layout); 'one' or empty: one "
                                          'process per node (or what the YAML says)'),
        OpaqueFunction(function=_nodes),
    ])
