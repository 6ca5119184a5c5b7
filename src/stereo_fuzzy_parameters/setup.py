from setuptools import find_packages, setup

package_name = 'stereo_fuzzy_parameters'

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
    maintainer='stereo-fuzzy engineering',
    maintainer_email='engineering@stereo-fuzzy.dev',
    description='Node parameters written once: typed settings, descriptors, validation.',
    license='Apache-2.0',
)
