# Two capture devices as a stereo camera: stereo_camera_node publishes
# <namespace>/left|right/image_raw + camera_info, which the camera_rig and chain sets pair.
# Its devices and calibration files come from the stereo_camera_node section of params_file.
#   ros2 launch stereo_fuzzy_perception stereo_camera.launch.py params_file:=my_rig.yaml
#
# The processes come from chain_processes.yaml beside this file, which the repository's
# process starter (chain/processes.py, launch_chain) reads too.
from pathlib import Path

from stereo_fuzzy_perception.bringup.chain_description import DESCRIPTION_FILE, launch_description

PROCESS_SET = 'stereo_camera'


def generate_launch_description():
    """Return the launch description of the stereo_camera set."""
    return launch_description(PROCESS_SET, Path(__file__).with_name(DESCRIPTION_FILE))
