from glob import glob

from setuptools import find_packages, setup

package_name = 'cartesian_3p_driver'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/urdf', glob('urdf/*.urdf')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='stereo-fuzzy engineering',
    maintainer_email='engineering@stereo-fuzzy.dev',
    description='G-code driver and Grbl simulator for a 3-axis Cartesian gantry.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'gantry_driver_node = cartesian_3p_driver.gantry_driver_node:main',
            'fake_gantry = cartesian_3p_driver.fake_gantry:main',
            'gantry = cartesian_3p_driver.gantry_command:main',
        ],
    },
)
