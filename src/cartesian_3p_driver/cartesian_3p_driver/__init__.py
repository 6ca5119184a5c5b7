"""Driver and simulator for a 3-axis Cartesian gantry with a Grbl-compatible controller."""
