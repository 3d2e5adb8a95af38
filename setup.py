"""Build script for the vessel_kinematics ament_python package."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'vessel_kinematics'

setup(
    name=package_name,
    version='0.2.0',  # as package.xml's <version>
    packages=find_packages(exclude=['test', 'bench']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    # The dependencies are package.xml's (rosdep keys); the development venv's pins are in
    # .ci/requirements.txt.
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='vessel_kinematics maintainers',
    maintainer_email='maintainers@vessel-kinematics.dev',
    url='https://vessel-kinematics.dev',
    description="Fossen's kinematics of marine craft for ROS 2: core, navigator node, replay.",
    license='BSD-3-Clause',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'navigator = vessel_kinematics.ros.navigator:main',
            'replay = vessel_kinematics.tools.replay:main',
            'simulate = vessel_kinematics.tools.sim:main',
        ],
    },
)
