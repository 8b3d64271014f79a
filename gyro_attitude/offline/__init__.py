"""Offline pipelines without a ROS graph (replay, simulate, allan): library functions that read
and write files through ``io`` and compute through ``core``; the CLI in ``commands`` only parses."""
