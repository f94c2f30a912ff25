"""One module per ``teleop`` subcommand (see :mod:`teleop.cli`)."""
