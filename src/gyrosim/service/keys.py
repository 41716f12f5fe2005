"""Zenoh key expressions of the gyrosim service: the only module that builds them.

Keys (docs/service.md; the prefix defaults to ``gyrosim``)::

    <prefix>/<scene>/<body>/state    application/json;gyrosim.BodyState
    <prefix>/<scene>/<body>/tf       application/cdr;tf2_msgs/msg/TFMessage
    <prefix>/<scene>/<body>/imu      application/cdr;sensor_msgs/msg/Imu
    <prefix>/<scene>/<body>/torque   application/json {"x", "y", "z"} (subscribed by the service)
    <prefix>/<scene>/<body>/motor    application/json {"torque"} (subscribed: a tree body's hinge motor)
    <prefix>/<scene>/<body>/params   queryable: current parameters as JSON
    <prefix>/<scene>/alive           liveliness token

An MCAP channel carries the topic ``"/" + key``: :func:`topic_for_key` and :func:`key_for_topic` are defined in
:mod:`gyrosim.telemetry.topics` (formats know no transport) and re-exported here.

Examples
--------
>>> from gyrosim.service.keys import BodyKeys, alive_key, parse_key
>>> BodyKeys("gyroscope", "gyro").state
'gyrosim/gyroscope/gyro/state'
>>> alive_key("gyroscope", prefix="lab")
'lab/gyroscope/alive'
>>> parse_key("gyrosim/gyroscope/gyro/imu")
KeyParts(prefix='gyrosim', scene='gyroscope', body='gyro', kind='imu')
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import ConfigError
from ..telemetry.topics import key_for_topic, topic_for_key

__all__ = [
    "DEFAULT_PREFIX",
    "BODY_KINDS",
    "PUBLISHED_KINDS",
    "COMMAND_KINDS",
    "BodyKeys",
    "KeyParts",
    "body_key",
    "alive_key",
    "scene_wildcard",
    "all_wildcard",
    "parse_key",
    "topic_for_key",
    "key_for_topic",
    "check_chunk",
    "check_key_expr",
]

#: Default first chunk of every key.
DEFAULT_PREFIX = "gyrosim"

#: ROS 2 over Zenoh (:mod:`gyrosim.service.ros2`): rmw_zenoh's wire protocols, ``jazzy`` (also Kilted and Rolling:
#: the same keys, type hashes and attachment) and ``humble`` (no type hashes: its keys carry
#: ``TypeHashNotSupported``).
ROS_DISTROS = ("jazzy", "humble")
#: The per-body key kinds, in the order of docs/service.md (``motor``: tree scenes' hinge motors).
BODY_KINDS = ("state", "tf", "imu", "torque", "params", "motor")
#: The kinds the service subscribes: commands (inputs) it takes.
COMMAND_KINDS = ("torque", "motor")
#: The kinds the service publishes (and records) for every body.
PUBLISHED_KINDS = ("state", "tf", "imu")

_FORBIDDEN = set("*$?#/") | {" "}


def check_key_expr(value: str, field: str = "--key") -> str:
    """Return ``value`` if it is a valid Zenoh key expression (wildcards allowed), as Zenoh itself judges it.

    Raises
    ------
    ConfigError
        Naming ``field`` and what is allowed (an empty expression, an empty chunk, a leading or trailing ``/``,
        a misplaced wildcard), before any session or file is opened.

    Examples
    --------
    >>> check_key_expr("gyrosim/**")
    'gyrosim/**'
    """
    import zenoh

    try:
        if not isinstance(value, str) or not value:
            raise ValueError("empty")
        zenoh.KeyExpr(value)
    except (ValueError, zenoh.ZError):
        raise ConfigError(field, value, "a Zenoh key expression: non-empty chunks separated by '/', no leading "
                                        "or trailing '/', wildcards '*' (one chunk) and '**' (any chunks) as "
                                        "whole chunks, e.g. gyrosim/** or gyrosim/gyroscope/*/state") from None
    return value


def check_chunk(value: str, field: str) -> str:
    """Return ``value`` if it is one valid, wildcard-free key chunk.

    Raises
    ------
    ConfigError
        If it is empty, not a string, or holds ``/``, ``*``, ``$``, ``?``, ``#`` or a space.

    Examples
    --------
    >>> check_chunk("heavy_top", "scene")
    'heavy_top'
    """
    if not isinstance(value, str) or not value or any(c in _FORBIDDEN for c in value):
        raise ConfigError(field, value, "a non-empty key chunk without '/', '*', '$', '?', '#' or spaces")
    return value


def _check_prefix(prefix: str) -> str:
    if not isinstance(prefix, str) or not prefix:
        raise ConfigError("prefix", prefix, "a non-empty key expression without wildcards")
    for chunk in prefix.split("/"):
        check_chunk(chunk, "prefix")
    return prefix


def body_key(scene: str, body: str, kind: str, *, prefix: str = DEFAULT_PREFIX) -> str:
    """Key ``<prefix>/<scene>/<body>/<kind>`` for one of :data:`BODY_KINDS`."""
    if kind not in BODY_KINDS:
        raise ConfigError("kind", kind, f"one of {', '.join(BODY_KINDS)}")
    return f"{_check_prefix(prefix)}/{check_chunk(scene, 'scene')}/{check_chunk(body, 'body')}/{kind}"


def alive_key(scene: str, *, prefix: str = DEFAULT_PREFIX) -> str:
    """Liveliness token key ``<prefix>/<scene>/alive``."""
    return f"{_check_prefix(prefix)}/{check_chunk(scene, 'scene')}/alive"


def scene_wildcard(scene: str, *, prefix: str = DEFAULT_PREFIX) -> str:
    """Key expression ``<prefix>/<scene>/**`` matching everything of one scene."""
    return f"{_check_prefix(prefix)}/{check_chunk(scene, 'scene')}/**"


def all_wildcard(*, prefix: str = DEFAULT_PREFIX) -> str:
    """Key expression ``<prefix>/**`` matching every gyrosim key."""
    return f"{_check_prefix(prefix)}/**"


@dataclass(frozen=True)
class BodyKeys:
    """Every key of one body.

    Parameters
    ----------
    scene, body : str
        Scene and body names (single key chunks).
    prefix : str
        First chunk(s) of the key, default ``gyrosim``.
    """

    scene: str
    body: str
    prefix: str = DEFAULT_PREFIX

    def __post_init__(self):
        _check_prefix(self.prefix)
        check_chunk(self.scene, "scene")
        check_chunk(self.body, "body")

    def key(self, kind: str) -> str:
        """The key of ``kind`` (one of :data:`BODY_KINDS`)."""
        return body_key(self.scene, self.body, kind, prefix=self.prefix)

    @property
    def state(self) -> str:
        return self.key("state")

    @property
    def tf(self) -> str:
        return self.key("tf")

    @property
    def imu(self) -> str:
        return self.key("imu")

    @property
    def torque(self) -> str:
        return self.key("torque")

    @property
    def params(self) -> str:
        return self.key("params")

    @property
    def motor(self) -> str:
        return self.key("motor")


@dataclass(frozen=True)
class KeyParts:
    """A gyrosim key split into its parts; ``body`` is None for ``alive``."""

    prefix: str
    scene: str
    body: str | None
    kind: str


def parse_key(key: str) -> KeyParts | None:
    """Split a concrete gyrosim key; None if it is not one (e.g. a foreign key).

    The prefix may hold several chunks: the last three (or two for ``alive``) are taken as scene, body, kind.
    """
    chunks = str(key).strip("/").split("/")
    if len(chunks) >= 3 and chunks[-1] == "alive":
        return KeyParts("/".join(chunks[:-2]), chunks[-2], None, "alive")
    if len(chunks) >= 4 and chunks[-1] in BODY_KINDS:
        return KeyParts("/".join(chunks[:-3]), chunks[-3], chunks[-2], chunks[-1])
    return None
