"""Telemetry: message encodings (JSON, ROS 2 CDR), the MCAP recorder, recover, info, plot and replay.

Only this package and :mod:`gyrosim.service` import ``mcap`` and ``zenoh``.
"""
