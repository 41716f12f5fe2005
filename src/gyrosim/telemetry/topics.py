"""Zenoh key <-> MCAP topic: the only module that maps one to the other.

An MCAP channel (and a Foxglove live channel) carries the topic ``"/" + key``; a replay publishes a topic back on
the key without the leading ``/``. :mod:`gyrosim.service.keys` builds the keys themselves and re-exports these
two functions.

Examples
--------
>>> topic_for_key("gyrosim/gyroscope/gyro/state")
'/gyrosim/gyroscope/gyro/state'
>>> key_for_topic("/gyrosim/gyroscope/gyro/state")
'gyrosim/gyroscope/gyro/state'
"""

from __future__ import annotations

__all__ = ["topic_for_key", "key_for_topic"]


def topic_for_key(key: str) -> str:
    """MCAP topic of a Zenoh key: ``"/" + key`` (a key given with a leading ``/`` is kept)."""
    key = str(key)
    return key if key.startswith("/") else "/" + key


def key_for_topic(topic: str) -> str:
    """Zenoh key of an MCAP topic written by :func:`topic_for_key`."""
    topic = str(topic)
    return topic[1:] if topic.startswith("/") else topic
