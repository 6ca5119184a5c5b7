# One stereo camera rig: stereo_sync_node, correlation_node and fuzzy_best_point_node, from
# images to best points, without a gantry.
#   ros2 launch stereo_fuzzy_perception camera_rig.launch.py params_file:=my_rig.yaml
#
# The processes come from chain_processes.yaml beside this file, which the repository's
# process starter (chain/processes.py, launch_chain) reads too.
from pathlib import Path

from stereo_fuzzy_perception.bringup.chain_description import DESCRIPTION_FILE, launch_description

PROCESS_SET = 'camera_rig'


def generate_launch_description():
    """Return the launch description of the camera_rig set."""
    return launch_description(PROCESS_SET, Path(__file__).with_name(DESCRIPTION_FILE))
