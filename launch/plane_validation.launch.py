"""Launch plane_validation_node (or, with managed:=true, plane_validation_lifecycle_node) with the
package's params file, a remappable input topic and the large-cloud Fast DDS profile.

    ros2 launch plane_validation plane_validation.launch.py cloud:=/camera/depth/points
    ros2 launch plane_validation plane_validation.launch.py namespace:=front managed:=true use_sim_time:=true

Arguments: namespace, use_sim_time, params_file, cloud, managed, and large_clouds (default true: sets
FASTRTPS_DEFAULT_PROFILES_FILE to config/fastdds_large_clouds.xml for the node, without which Fast DDS
loses most clouds over 0.5 MB between processes; false when the environment sets its own profile).
A managed node starts unconfigured: a lifecycle manager (or `ros2 lifecycle set`) configures and
activates it.
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, SetEnvironmentVariable
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import LifecycleNode, Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description() -> LaunchDescription:
    config = os.path.join(get_package_share_directory('plane_validation'), 'config')
    managed = LaunchConfiguration('managed')
    node = dict(package='plane_validation', name='plane_validation', namespace=LaunchConfiguration('namespace'),
                parameters=[LaunchConfiguration('params_file'),
                            {'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'), value_type=bool)}],
                remappings=[('cloud', LaunchConfiguration('cloud'))], output='screen')
    return LaunchDescription([
        DeclareLaunchArgument('namespace', default_value='', description='namespace of the node'),
        DeclareLaunchArgument('use_sim_time', default_value='false', description='use /clock (bag replay)'),
        DeclareLaunchArgument('params_file', default_value=os.path.join(config, 'params.yaml'),
                              description='parameters file (keyed /**: any node name)'),
        DeclareLaunchArgument('cloud', default_value='cloud', description='input PointCloud2 topic'),
        DeclareLaunchArgument('managed', default_value='false',
                              description='start the lifecycle node (configure and activate it from a manager)'),
        DeclareLaunchArgument('large_clouds', default_value='true',
                              description='set the large-cloud Fast DDS profile (config/fastdds_large_clouds.xml)'),
        SetEnvironmentVariable('FASTRTPS_DEFAULT_PROFILES_FILE', os.path.join(config, 'fastdds_large_clouds.xml'),
                               condition=IfCondition(LaunchConfiguration('large_clouds'))),
        Node(executable='plane_validation_node', condition=UnlessCondition(managed), **node),
        LifecycleNode(executable='plane_validation_lifecycle_node', condition=IfCondition(managed), **node),
    ])
