"""Controllers: pure step functions for the master, controller and hand roles.

* :mod:`teleop.control.interface` - parameters, outputs, :class:`ControllerSuite`;
* :mod:`teleop.control.registry` - ``CONTROLLERS`` by config name (two-layer, direct, tdpa);
* :mod:`teleop.control.energy_channel` - monotone energy totals, ``energy_balance``;
* :mod:`teleop.control.stability_limit` - predicted stability limit of direct control.

The equations and references are in ``docs/controllers.md``.
"""
