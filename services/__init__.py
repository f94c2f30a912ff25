"""Services: master, controller and hand wiring (the composition root)."""
