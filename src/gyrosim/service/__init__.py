"""The Zenoh service: keys, every Zenoh loop (serve, record, replay), the Foxglove live server and the command
line of serve, record and replay."""
