"""teleop.diagnose: system identification of missing physics (``teleop diagnose``)."""
