"""Bringing the chain up: the one description of its processes, read by the launch files and
launch_chain (chain/processes.py)."""
