"""ament_python build of fourbar_ros (also installable with plain pip)."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'fourbar_ros'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, f'{PACKAGE}.*']),  # not benchmarks/ or test/
    package_data={PACKAGE: ['py.typed', 'data/demo_sweep/*']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        (f'share/{PACKAGE}/config', glob('config/*.yaml')),
        (f'share/{PACKAGE}/config/security', glob('config/security/*.xml')),  # the SROS2 policy
        (f'share/{PACKAGE}/launch', glob('launch/*.launch.py')),
        (f'share/{PACKAGE}/rviz', glob('rviz/*.rviz')),
        (f'share/{PACKAGE}/bags/demo_sweep', glob(f'{PACKAGE}/data/demo_sweep/*')),
    ],
    install_requires=['setuptools', 'numpy', 'PyYAML', 'ruckig'],  # ruckig: jerk-limited motion planning
    extras_require={
        'bags': ['rosbags', 'mcap', 'mcap-ros2-support'],
        'plot': ['matplotlib', 'pillow'],
        'plant': ['mujoco'],  # the MuJoCo plant (fourbar_ros.plant)
        # mujoco: the torque witness (test/core/test_torque_witness.py)
        'test': ['pytest', 'hypothesis', 'mpmath', 'ruff', 'mypy', 'types-PyYAML',
                 'catkin_pkg', 'colcon-core', 'colcon-ros', 'colcon-python-setup-py', 'pytest-codeblocks',
                 'pytest-xdist', 'lxml', 'mujoco', 'rosdep'],
    },
    zip_safe=True,
    maintainer='fourbar_ros developers',
    maintainer_email='fourbar-ros@example.org',
    description='Four-bar antenna tilt linkage: kinematics, statics, rclpy node and bag tools.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'fourbar = fourbar_ros.commands:main',
            'fourbar_node = fourbar_ros.node:main',
            'fourbar_sim_actuator = fourbar_ros.plant.sim_drive:sim_actuator_main',
            'fourbar_drive_bridge = fourbar_ros.drive.run:main',
            'fourbar_mujoco_drive = fourbar_ros.plant.run:main',
        ],
    },
)
