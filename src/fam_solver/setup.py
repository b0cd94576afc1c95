from setuptools import find_packages, setup

package_name = 'fam_solver'

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
    description='Finite Arc Method (FAM) forward model of a planar catheter, a reference Kirchhoff '
                'rod solver, and the fam_solver_node.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'fam_solver_node = catheter_common.node_entry:fam_solver__fam_solver_node',
        ],
    },
)
