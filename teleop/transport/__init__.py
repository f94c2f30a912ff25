"""teleop.transport."""
