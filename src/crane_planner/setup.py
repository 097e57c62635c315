from glob import glob

from setuptools import find_packages, setup

package_name = 'crane_planner'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools', 'numpy', 'scipy', 'casadi', 'matplotlib', 'pyyaml', 'crane_msgs_py'],
    # The nodes never need the simulator; the offline tools that simulate a plan (crane-plan, crane-demo) do.
    extras_require={'sim': ['crane_sim']},
    zip_safe=True,
    maintainer='Crane trajectory server team',
    maintainer_email='crane@example.com',
    description='Anti-sway reference planner, CLI, planner and streamer nodes',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'planner = crane_planner.nodes.planner_node:main',
            'streamer = crane_planner.nodes.streamer_node:main',
            'crane-plan = crane_planner.tools.cli:main',
            'crane-demo = crane_planner.tools.demo:main',
            'crane-record = crane_planner.tools.record:main',
            'crane-teleop = crane_planner.tools.teleop:main',
        ],
    },
)
