from setuptools import find_packages, setup

package_name = 'impedance_master'

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
    description='Impedance-matching force feedback: slave-side identification, master-side IMA and '
                'DFR rendering, simulated haptic device and operator.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            ('impedance_identifier_node = '
             'catheter_common.node_entry:impedance_master__impedance_identifier_node'),
            'ima_master_node = catheter_common.node_entry:impedance_master__ima_master_node',
            'sim_haptic_node = catheter_common.node_entry:impedance_master__sim_haptic_node',
        ],
    },
)
