from setuptools import find_packages, setup

package_name = 'sim_slave'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Catheter teleoperation team',
    maintainer_email='dev@catheter-teleop.example',
    description='Simulated patient side: insertion robot, vessel interaction, force sensor, camera '
                'stream, UDP-like link.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_slave_node = catheter_common.node_entry:sim_slave__sim_slave_node',
            'camera_node = catheter_common.node_entry:sim_slave__camera_node',
        ],
    },
)
