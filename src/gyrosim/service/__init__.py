"""The Zenoh service: keys, the serve loop, the recorder process and the command line."""
