"""Subcommands of the ``gyro-attitude`` console command (one module each)."""
