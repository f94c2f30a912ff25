"""teleop.analysis."""
