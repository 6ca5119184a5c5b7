"""Node parameters written once, shared by every node of the project.

`spec` is ROS-free: a node's settings type is a frozen dataclass of `parameter()` fields, from
which the ParameterSpec list (names, defaults, ranges, docs; the README tables) is derived and
into which declared values are read. `world` is the world frame and workspace box that several
nodes share; `qos` the QoS profiles both packages use, so both ends of a topic agree.
`declaration` declares a settings type on an rclpy node (descriptors, validation of the
proposed settings object on every set) and `run_node` runs a node whose start-up errors end it
with one line.
"""
