"""The gantry driver's QoS profiles by name: the shared ones and the driver's own.

The profiles the perception nodes use too are defined once in stereo_fuzzy_parameters.qos and
re-exported here, so a node imports one module:

- Commands (best_point targets): the perception's RESULTS profile (reliable, keep last 10), the
  same object, so the publisher and this subscriber always match.
- Diagnostics and /tf: as stereo_fuzzy_parameters.qos defines them.

The driver's own:

- Driver state (gantry/state): reliable, transient local, keep last 1, so a late subscriber
  gets the current state at once.
- Joint states: reliable, keep last 10 (what robot_state_publisher expects).
"""

from stereo_fuzzy_parameters.qos import DIAGNOSTICS, RESULTS, TF, reliable

__all__ = ['COMMANDS', 'DIAGNOSTICS', 'DRIVER_STATE', 'JOINT_STATES', 'TF']

COMMANDS = RESULTS
DRIVER_STATE = reliable(1, transient_local=True)
JOINT_STATES = reliable(10)
