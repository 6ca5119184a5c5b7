"""Start the whole chain as separate processes, as `ros2 launch` would; the demo runner."""
