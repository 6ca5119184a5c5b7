from glob import glob

from setuptools import Extension, find_packages, setup

package_name = 'stereo_fuzzy_perception'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml') + glob('config/*.xml')),
        # launch files and the process description they (and chain/processes.py) read
        ('share/' + package_name + '/launch',
         glob('launch/*.launch.py') + glob('launch/*.yaml')),
    ],
    package_data={package_name: ['data/*.yaml', 'data/*.npz', 'core/matching/*.pyi']},
    # The matcher's kernel, the whole matcher behind one Python function (see its header
    # comment). -ffp-contract=off: no fused multiply-add, so the vectorised and the scalar loops
    # round alike and results do not depend on the CPU. -fno-math-errno, -fno-trapping-math:
    # sqrt and branch-free selects vectorise (neither changes a result: errno and FP exception
    # flags are never read). -pthread: its worker threads.
    # Its translation units share window_matcher_kernel.h (which lists them).
    ext_modules=[Extension(package_name + '.core.matching._window_matcher_kernel',
                           sources=[f'{package_name}/core/matching/{unit}.c' for unit in (
                               'window_matcher_kernel', 'matcher_prepare', 'matcher_correlate',
                               'matcher_threads', 'matcher_triangulate')],
                           depends=[package_name + '/core/matching/window_matcher_kernel.h'],
                           extra_compile_args=['-O3', '-ffp-contract=off', '-fno-math-errno',
                                               '-fno-trapping-math', '-pthread'],
                           extra_link_args=['-pthread'])],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='stereo-fuzzy engineering',
    maintainer_email='engineering@stereo-fuzzy.dev',
    description='Stereo perception and fuzzy best-point selection for a 3P gantry.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'stereo_sync_node = stereo_fuzzy_perception.nodes.stereo_sync_node:main',
            'correlation_node = stereo_fuzzy_perception.nodes.correlation_node:main',
            'fuzzy_best_point_node = stereo_fuzzy_perception.nodes.fuzzy_best_point_node:main',
            'rig_transforms_node = stereo_fuzzy_perception.nodes.rig_transforms_node:main',
            'stereo_camera_node = stereo_fuzzy_perception.nodes.stereo_camera_node:main',
            'rig_calibration = stereo_fuzzy_perception.rig.rig_calibration:main',
            'bag = stereo_fuzzy_perception.bag.bag_tool:main',
            'render_scenes = stereo_fuzzy_perception.simulation.scene_bag_writer:main',
        ],
    },
)
