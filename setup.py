"""ament_python package definition; also installable with pip (see README)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'plane_validation'

# ROS 2 Jazzy from PyPI for machines without an apt-installed ROS. On a robot these come from
# apt through package.xml/rosdep instead, so they are an extra, never a hard requirement.
ROS_WHEELS = [
    'ros-jazzy-rclpy[fastrtps]',
    'ros-jazzy-sensor-msgs',
    'ros-jazzy-std-msgs',
    'ros-jazzy-geometry-msgs',
    'ros-jazzy-diagnostic-msgs',
    'ros-jazzy-visualization-msgs',
    'ros-jazzy-lifecycle-msgs',
]
CORE = [
    'numpy>=1.24',
    'numba>=0.59',  # the compiled per-frame kernels (core/kernels.py)
    'scipy>=1.10',
    'rosbags>=0.10',  # get_typestore(Stores.ROS2_JAZZY)
    'matplotlib>=3.6',
    'tqdm>=4.60',
    'pypcd4>=1.0',  # optional .pcd reading in the CLI; pip only (no rosdep key)
    'joblib>=1.3',  # the tuning sweep's worker processes (tune_jobs): the loky it carries
    'psutil>=5.8',  # lets loky stop the workers on Ctrl-C (without it, it runs pgrep, which the Ctrl-C kills)
    'threadpoolctl>=3.0',  # one BLAS thread per process (see pipeline.limit_blas_threads)
    'plyfile>=1.0',  # .ply reading/writing in the CLI (GPL-3.0; imported only for .ply files)
    'pillow>=8',  # palette PNGs of the index plots (matplotlib depends on it anyway)
]
# `plane-validation batch --ray`: bags on a Ray cluster (docs/batch.md); pip only, no rosdep key.
FLEET = ['ray>=2.9']

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml') + glob('config/*.xml') + glob('config/*.rviz')
         + glob('config/*.json')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        ('share/' + PACKAGE + '/bags/room', glob('bags/room/*')),  # the demo's bag (cli demo_bag)
    ],
    # ament convention: runtime dependencies are declared in package.xml and resolved by
    # rosdep; pip users take them from the extras below.
    install_requires=['setuptools'],
    extras_require={
        'core': CORE,
        'ros': CORE + ROS_WHEELS,
        'fleet': CORE + ROS_WHEELS + FLEET,
        'test': ['pytest>=7', 'hypothesis>=6', 'scikit-learn>=1.2'],
    },
    zip_safe=True,
    maintainer='plane_validation developers',
    maintainer_email='dev@plane-validation.invalid',
    description='Self-validating sequential RANSAC plane detection for ROS 2 point clouds.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'plane_validation_node = plane_validation.ros:main',
            'plane_validation_lifecycle_node = plane_validation.ros:lifecycle_main',
            'plane-validation = plane_validation.cli:main',
        ],
    },
)
