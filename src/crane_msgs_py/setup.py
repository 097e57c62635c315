from setuptools import find_packages, setup

package_name = 'crane_msgs_py'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name + '.runtime': ['fastdds_profiles.xml', 'fastdds_loopback.xml']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools', 'numpy'],
    zip_safe=True,
    maintainer='Crane trajectory server team',
    maintainer_email='crane@example.com',
    description='Crane trajectory server conventions on standard ROS 2 interfaces',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [

        ],
    },
)
