"""ament_python build of sins_align_ros."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'sins_align_ros'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*', 'bench', 'bench.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml')),
        ('share/' + PACKAGE + '/launch', glob('launch/*.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='sins_align_ros developers',
    maintainer_email='sins-align@example.com',
    description='Strapdown INS initial alignment for ROS 2: filters, simulator, replay.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'alignment_node = sins_align_ros.ros.alignment_node:main',
            'alignment_lifecycle_node = sins_align_ros.ros.alignment_lifecycle_node:main',
            'simulator_node = sins_align_ros.ros.simulator_node:main',
            'sins_align_demo = sins_align_ros.ros.demo:main',
            'sins_align_replay = sins_align_ros.cli.replay:run',
        ],
    },
)
