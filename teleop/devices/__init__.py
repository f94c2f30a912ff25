"""teleop.devices."""
