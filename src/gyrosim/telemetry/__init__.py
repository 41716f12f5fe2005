"""Telemetry formats: message encodings (JSON, ROS 2 CDR), the key <-> topic mapping, MCAP writing and reading,
recover, info, plots, and the Foxglove JSON-schema rules.

Formats know no transport: nothing here imports :mod:`gyrosim.service` or ``zenoh``; the Zenoh loops (serve,
record, replay) live in :mod:`gyrosim.service`.
"""
