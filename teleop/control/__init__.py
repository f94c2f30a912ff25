"""teleop.control."""
