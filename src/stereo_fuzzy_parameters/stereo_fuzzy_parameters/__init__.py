"""Node parameters written once, shared by every node of the project.

`spec` is ROS-free (names, defaults, ranges, docs; the README tables are generated from it);
`declaration` declares specs on an rclpy node with descriptors and an on-set validation.
"""
