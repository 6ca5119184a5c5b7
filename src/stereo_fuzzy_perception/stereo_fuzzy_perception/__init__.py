"""Stereo perception and fuzzy best-point selection (Ghayoumi and Shayganfar, 2007)."""
