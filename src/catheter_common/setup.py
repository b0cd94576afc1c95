from setuptools import find_packages, setup

package_name = 'catheter_common'

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
    description='Shared ROS 2 plumbing for the catheter packages: topic names and QoS, node runner '
                'with clean shutdown, diagnostics helper.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
        ],
    },
)
