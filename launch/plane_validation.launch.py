"""Launch plane_validation_node with the package's params file and a remappable input topic.

    ros2 launch plane_validation plane_validation.launch.py cloud:=/camera/depth/points
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def generate_launch_description() -> LaunchDescription:
    share = get_package_share_directory('plane_validation')
    return LaunchDescription([
        DeclareLaunchArgument('cloud', default_value='cloud', description='input PointCloud2 topic'),
        DeclareLaunchArgument('params_file', default_value=os.path.join(share, 'config', 'params.yaml'),
                              description='parameters file'),
        Node(package='plane_validation', executable='plane_validation_node', name='plane_validation',
             parameters=[LaunchConfiguration('params_file')],
             remappings=[('cloud', LaunchConfiguration('cloud'))], output='screen'),
    ])
