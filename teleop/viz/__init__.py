"""teleop.viz."""
