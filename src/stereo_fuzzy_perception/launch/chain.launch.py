# The whole chain on a real gantry: the three perception nodes and gantry_driver_node on the
# Grbl controller at port:=DEVICE (default /dev/ttyACM0).
#   ros2 launch stereo_fuzzy_perception chain.launch.py port:=/dev/ttyUSB0 params_file:=my_rig.yaml
#
# The processes come from chain_processes.yaml beside this file, which the repository's
# process starter (chain/processes.py, launch_chain) reads too.
from pathlib import Path

from stereo_fuzzy_perception.bringup.chain_description import DESCRIPTION_FILE, launch_description

PROCESS_SET = 'chain'


def generate_launch_description():
    """Return the launch description of the chain set."""
    return launch_description(PROCESS_SET, Path(__file__).with_name(DESCRIPTION_FILE))
