import glob

from setuptools import find_packages, setup

package_name = 'catheter_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # scenarios and the launch file, found through ament_index_python (scenario.config_dir)
        ('share/' + package_name + '/config', sorted(glob.glob('config/*.yaml'))),
        ('share/' + package_name + '/launch', sorted(glob.glob('launch/*.launch.py'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Catheter teleoperation team',
    maintainer_email='dev@catheter-teleop.example',
    description='Scenario runner (launchless, lockstep or real time), MCAP recorder, replay, '
                'analysis and plots for the catheter node graph.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'run_scenario = catheter_bringup.run_scenario:main',
            'recorder_node = catheter_common.node_entry:catheter_bringup__recorder_node',
            'force_source_node = catheter_common.node_entry:catheter_bringup__force_source_node',
            'recover_bag = catheter_bringup.bagfile:main',
            'catheter_topic = catheter_bringup.topic_tool:main',
        ],
    },
)
