"""vibration_node with the monitor, in one namespace.

Usage (after ``make run``'s set-up and ``make ros2cli``, with ``AMENT_PREFIX_PATH=.venv``; or
on a ROS 2 Jazzy machine after ``colcon build``)::

    ros2 launch impact_damper_sim vibration.launch.py
    ros2 launch impact_damper_sim vibration.launch.py scene:=rbs namespace:=rbs \
        record:=rbs.mcap monitor:=false
    ros2 launch impact_damper_sim vibration.launch.py params_file:=/path/to/my_params.yaml

Arguments: ``scene`` (name or file), ``namespace``, ``params_file`` (the node's parameters;
default the package's ``config/vibration_node.yaml``), ``record`` (MCAP path; empty = not
recording), ``real_time_factor``, ``monitor`` (true/false). Values given as arguments win
over the params file. ``scene`` and ``record`` are passed as strings and ``real_time_factor``
as a float whatever they look like: launch would otherwise read ``scene:=0123`` or
``record:=2024`` as YAML integers, which the node's string parameters refuse.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

PACKAGE = 'impact_damper_sim'


def generate_launch_description():
    """The launch description: arguments, ``vibration_node`` and ``monitor``."""
    scene = LaunchConfiguration('scene')
    namespace = LaunchConfiguration('namespace')
    params_file = LaunchConfiguration('params_file')
    record = LaunchConfiguration('record')
    real_time_factor = LaunchConfiguration('real_time_factor')
    monitor = LaunchConfiguration('monitor')
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='hpotp',
                              description='scene name (config/scenes/<name>.yaml) or file'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of both nodes (one machine each)'),
        DeclareLaunchArgument(
            'params_file',
            default_value=PathJoinSubstitution([FindPackageShare(PACKAGE), 'config',
                                                'vibration_node.yaml']),
            description="vibration_node's parameters file"),
        DeclareLaunchArgument('record', default_value='',
                              description='MCAP file to record to; empty = not recording'),
        DeclareLaunchArgument('real_time_factor', default_value='1.0',
                              description='sim seconds per wall second; 0 = flat out'),
        DeclareLaunchArgument('monitor', default_value='true',
                              description='also run the monitor node'),
        Node(package=PACKAGE, executable='vibration_node', name='vibration_node',
             namespace=namespace, output='screen', emulate_tty=True,
             parameters=[params_file, {
                 'scene': ParameterValue(scene, value_type=str),
                 'record': ParameterValue(record, value_type=str),
                 'real_time_factor': ParameterValue(real_time_factor, value_type=float)}]),
        Node(package=PACKAGE, executable='monitor', name='monitor', namespace=namespace,
             output='screen', emulate_tty=True, condition=IfCondition(monitor)),
    ])
