from glob import glob

from setuptools import find_packages, setup

package_name = 'crane_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy', 'crane_msgs_py'],
    zip_safe=True,
    maintainer='Crane trajectory server team',
    maintainer_email='crane@example.com',
    description='Double-pendulum crane simulator (numpy core + ROS 2 node)',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim = crane_sim.nodes.sim_node:main',
        ],
    },
)
