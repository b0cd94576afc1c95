import glob

from setuptools import find_packages, setup

package_name = 'force_estimator'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['models/*.npz']},
    include_package_data=True,
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        # the shipped models also in share/ (ament_index_python), besides the package data
        ('share/' + package_name + '/models',
         sorted(glob.glob(package_name + '/models/*.npz'))),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='Catheter teleoperation team',
    maintainer_email='dev@catheter-teleop.example',
    description='Tip force estimation from Bezier control points: learned models (SVR, MLP) '
                'trained on simulation, and FAM inversion.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            ('force_estimator_node = '
             'catheter_common.node_entry:force_estimator__force_estimator_node'),
        ],
    },
)
