"""Install awp_ros: the core library, its console scripts and its data files."""

from glob import glob

from setuptools import find_packages, setup

package_name = 'awp_ros'
version = '0.1.0'  # the same as in package.xml

# One executable per job. `ros2 run awp_ros <name>` finds them in lib/awp_ros (setup.cfg).
executables = {
    'awp_node': 'awp_ros.node.node:main',
    'awp_replay': 'awp_ros.cli.replay:main',
    'awp_eval': 'awp_ros.cli.eval:main',
    'awp_bench': 'awp_ros.cli.bench:main',
    'awp_demo': 'awp_ros.demo.demo:main',
    'awp_param': 'awp_ros.cli.param:main',
}

setup(
    name=package_name,
    version=version,
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['py.typed', 'node/fastdds_profile.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='awp_ros developers',
    maintainer_email='awp-ros@example.org',
    description='AWP, FWP and FWS wrench polytopes and feasibility margins of legged robots.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [f'{name} = {target}' for name, target in executables.items()],
    },
)
