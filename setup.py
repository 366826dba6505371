"""ament_python build of sins_align_ros."""
import os
import subprocess
import sys
from glob import glob

from setuptools import find_packages, setup
from setuptools.command.install import install

PACKAGE = 'sins_align_ros'


class InstallWithKernels(install):
    """``install``, then the kernels compiled ahead of time into the installed package.

    ``python -m sins_align_ros.cli.build_kernels`` (numba.pycc and a C compiler) writes
    ``_aot_kernels`` beside the installed sources, so that no process of the package
    imports numba (about 0.7 s of every start). Where it cannot be built the install
    goes on and the kernels are compiled just in time by numba, as before.
    """

    def run(self):
        super().run()
        lib = os.path.abspath(self.install_lib)
        env = dict(os.environ, PYTHONPATH=lib + os.pathsep + os.environ.get('PYTHONPATH', ''))
        done = subprocess.run([sys.executable, '-m', f'{PACKAGE}.cli.build_kernels',
                               os.path.join(lib, PACKAGE)], cwd=lib, env=env)
        if done.returncode != 0:
            print(f'{PACKAGE}: kernels not compiled ahead of time; numba will compile them '
                  'at first use', file=sys.stderr)


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
    cmdclass={'install': InstallWithKernels},
    entry_points={
        'console_scripts': [
            'alignment_node = sins_align_ros.ros.alignment_node:main',
            'alignment_lifecycle_node = sins_align_ros.ros.alignment_lifecycle_node:main',
            'simulator_node = sins_align_ros.ros.simulator_node:main',
            'sins_align_demo = sins_align_ros.ros.demo:main',
            'sins_align_replay = sins_align_ros.cli.replay:run',
            'sins_align_record = sins_align_ros.cli.record:main',
        ],
    },
)
