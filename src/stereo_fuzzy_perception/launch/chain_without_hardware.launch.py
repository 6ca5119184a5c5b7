# The whole chain with fake_gantry (a simulated Grbl controller on a pseudo-terminal) as the
# machine: what scripts/demo.sh starts.
#   ros2 launch stereo_fuzzy_perception chain_without_hardware.launch.py \
#     params_file:=chain/demo_params.yaml
#
# The processes come from chain_processes.yaml beside this file, which the repository's
# process starter (chain/processes.py, launch_chain) reads too.
from pathlib import Path

from stereo_fuzzy_perception.bringup.chain_description import DESCRIPTION_FILE, launch_description

PROCESS_SET = 'chain_without_hardware'


def generate_launch_description():
    """Return the launch description of the chain_without_hardware set."""
    return launch_description(PROCESS_SET, Path(__file__).with_name(DESCRIPTION_FILE))
