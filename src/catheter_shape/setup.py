from setuptools import find_packages, setup

package_name = 'catheter_shape'

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
    description='Image-based shape sensing: camera frame to ordered centreline to Bezier control '
                'points; synthetic camera.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'shape_node = catheter_common.node_entry:catheter_shape__shape_node',
        ],
    },
)
