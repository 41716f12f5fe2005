"""The Foxglove live view of ``gyrosim serve --foxglove [HOST:]PORT`` and ``gyrosim replay --foxglove [HOST:]PORT``:
a Foxglove WebSocket server (the ``foxglove-sdk`` package) streaming what the service (or the replay) publishes
on Zenoh.

Per body, on the topics of the MCAP recordings (``"/" + key``):

* ``.../state``: the same JSON ``gyrosim.BodyState`` bytes, with its JSON schema (Foxglove's rules);
* ``.../imu``: the same CDR ``sensor_msgs/msg/Imu`` bytes with the ``ros2msg`` definition;
* ``.../tf``: the transform parent -> body (``world`` -> body; in a tree scene from the parent body's frame, so
  the 3D panel draws the whole tree) as JSON ``foxglove.FrameTransform``, the schema Foxglove's 3D panel draws
  without any ROS support (the Zenoh key and the recordings keep CDR ``tf2_msgs/msg/TFMessage``); one message per
  transform, so in a scene with contact also ``world`` -> ``<body>/<shape>/contact`` for each contact point of the
  body's shapes (:mod:`gyrosim.service.serve`).

Log times are the wall clock at publication (ns since the Unix epoch), as in the recordings; the simulation
time is in the messages (``t``, header stamps, ``timestamp``). The server has its own ``foxglove.Context``, so
nothing else in the process logs into it. It speaks the Foxglove WebSocket protocol under the subprotocol
``foxglove.sdk.v1`` (the Foxglove app offers it); default host 127.0.0.1 (loopback only).
"""

from __future__ import annotations

import json
import logging

from ..errors import ConfigError, GyrosimError
from ..telemetry import messages as msg
from ..telemetry.topics import topic_for_key
from .config import ServiceConnectionError

__all__ = ["DEFAULT_HOST", "DEFAULT_PORT", "parse_host_port", "LiveView"]

log = logging.getLogger("gyrosim.service.live")

#: Default host of the WebSocket server: loopback only.
DEFAULT_HOST = "127.0.0.1"
#: Foxglove's default WebSocket port.
DEFAULT_PORT = 8765


def parse_host_port(value: str, flag: str = "--foxglove") -> tuple[str, int]:
    """``"8765"``, ``":8765"``, ``"0.0.0.0:8765"`` or ``"[::1]:8765"`` -> ``(host, port)``; host defaults to
    127.0.0.1.

    Examples
    --------
    >>> parse_host_port("8765"), parse_host_port("localhost:9000"), parse_host_port("[::1]:8765")
    (('127.0.0.1', 8765), ('localhost', 9000), ('::1', 8765))
    """
    text = str(value).strip()
    host, sep, port = text.rpartition(":")
    if not sep:
        host, port = "", text
    host = host.strip("[]") or DEFAULT_HOST
    try:
        p = int(port)
    except ValueError:
        raise ConfigError(flag, value, "[HOST:]PORT with a port number, e.g. 8765 or 127.0.0.1:8765") from None
    if not 0 <= p <= 65535:
        raise ConfigError(flag, value, "a port in 0..65535 (0: any free port)")
    return host, p


class LiveView:
    """A Foxglove WebSocket server with one channel per published key.

    Parameters
    ----------
    host, port : str, int
        Where to listen (port 0: a free port; :attr:`port` tells which).
    name : str
        Server name shown by Foxglove.
    bodies : iterable of gyrosim.service.keys.BodyKeys, optional
        Bodies whose channels are created before the server starts listening, so that a client connecting at
        any time sees them all in its first advertisement. (A channel created while a client is connected is
        advertised to it, but a subscription that arrives at once can be refused with "Unknown channel ID";
        that client then never gets the channel's messages.)
    recorded : iterable of (topic, message_encoding, schema or None), optional
        Channels of a recording (``gyrosim replay --foxglove``), also created before the server listens: each
        with its recorded message encoding and schema (an ``mcap.records.Schema``), except the CDR
        ``tf2_msgs/msg/TFMessage`` channels, which become ``foxglove.FrameTransform`` JSON as in the live view
        of ``gyrosim serve`` (:meth:`log_topic` converts their messages).

    Raises
    ------
    GyrosimError
        If ``foxglove-sdk`` is not installed (exit 2: install it).
    ServiceConnectionError
        If the server cannot listen (one line with the address and the flag to change; exit 1).
    """

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, name: str = "gyrosim", bodies=(),
                 recorded=()):
        try:
            import foxglove
        except ImportError:
            raise GyrosimError("--foxglove needs the foxglove-sdk package: pip install 'gyrosim[service]'") from None
        self._foxglove = foxglove
        self.context = foxglove.Context()
        self._channels: dict[str, object] = {}
        self._convert: dict[str, object] = {}  # topic -> payload converter (recorded tf -> FrameTransform)
        for keys in bodies:
            self.add_body(keys)
        for topic, message_encoding, schema in recorded:
            self.add_recorded(topic, message_encoding, schema)
        try:
            self.server = foxglove.start_server(name=name, host=host, port=int(port), context=self.context)
        except Exception as e:  # noqa: BLE001 - the SDK raises RuntimeError / its own errors
            why = " ".join(str(e).split())
            hint = ("the address is already in use" if "in use" in why.lower() or "os error 98" in why
                    else why)
            raise ServiceConnectionError(f"cannot start the Foxglove WebSocket server on {host}:{port}: {hint}; "
                                         "choose another with --foxglove HOST:PORT") from None
        self.host = host
        self.port = int(self.server.port)
        log.info("Foxglove live view on ws://%s:%d (Foxglove: Open connection > Foxglove WebSocket)",
                 host if ":" not in host else f"[{host}]", self.port)

    @property
    def url(self) -> str:
        host = self.host if ":" not in self.host else f"[{self.host}]"
        return f"ws://{host}:{self.port}"

    def _channel(self, topic: str, encoding: str, schema_name: str, schema_encoding: str, schema_data: bytes):
        ch = self._channels.get(topic)
        if ch is None:
            fg = self._foxglove
            schema = fg.Schema(name=schema_name, encoding=schema_encoding, data=schema_data)
            ch = fg.Channel(topic, message_encoding=encoding, schema=schema, context=self.context)
            self._channels[topic] = ch
        return ch

    def add_body(self, keys) -> None:
        """Advertise the state, tf and imu channels of one body (:class:`gyrosim.service.keys.BodyKeys`); a no-op
        for channels that exist."""
        state = msg.schema_for_encoding(msg.STATE_ENCODING)
        self._channel(topic_for_key(keys.state), "json", state.name, state.encoding, state.data)
        self._channel(topic_for_key(keys.tf), "json", msg.FRAME_TRANSFORM_SCHEMA_NAME, "jsonschema",
                      json.dumps(msg.FRAME_TRANSFORM_JSON_SCHEMA).encode())
        imu = msg.schema_for_encoding(msg.IMU_ENCODING)
        self._channel(topic_for_key(keys.imu), "cdr", imu.name, imu.encoding, imu.data)

    def add_recorded(self, topic: str, message_encoding: str, schema=None) -> bool:
        """Advertise a channel of a recording (see ``recorded``); False for a channel Foxglove cannot take (no
        message encoding)."""
        if not message_encoding:
            return False
        if message_encoding == "cdr" and schema is not None and schema.name == msg.TF_TYPE:
            self._channel(topic, "json", msg.FRAME_TRANSFORM_SCHEMA_NAME, "jsonschema",
                          json.dumps(msg.FRAME_TRANSFORM_JSON_SCHEMA).encode())
            self._convert[topic] = _frame_transforms_of_tf(schema)
            return True
        if schema is None or not schema.encoding:
            ch = self._channels.get(topic)
            if ch is None:
                ch = self._foxglove.Channel(topic, message_encoding=message_encoding, context=self.context)
                self._channels[topic] = ch
            return True
        self._channel(topic, message_encoding, schema.name, schema.encoding, bytes(schema.data))
        return True

    def log_topic(self, topic: str, data: bytes, log_time_ns: int) -> None:
        """Send one recorded message on its topic's channel (converted where :meth:`add_recorded` said so; a no-op
        for a topic without a channel, and for a payload that does not convert)."""
        ch = self._channels.get(topic)
        if ch is None:
            return
        convert = self._convert.get(topic)
        if convert is None:
            ch.log(data, log_time=int(log_time_ns))
            return
        try:
            out = convert(data)
        except Exception as e:  # noqa: BLE001 - a payload the decoder refuses: not streamed, never fatal
            log.debug("%s: a message that does not decode as %s: %s", topic, msg.TF_TYPE, e)
            return
        for payload in out:
            ch.log(payload, log_time=int(log_time_ns))

    def log(self, key: str, data: bytes, log_time_ns: int) -> None:
        """Send one message on the channel of ``key`` (a no-op for a key without a channel)."""
        ch = self._channels.get(topic_for_key(key))
        if ch is not None:
            ch.log(data, log_time=int(log_time_ns))

    def close(self) -> None:
        """Stop the server (clients see the connection close)."""
        try:
            self.server.stop()
        except Exception as e:  # noqa: BLE001 - closing is best effort
            log.debug("stopping the Foxglove server: %s", e)


def _frame_transforms_of_tf(schema):
    """A converter: CDR ``tf2_msgs/msg/TFMessage`` payload -> one ``foxglove.FrameTransform`` JSON per transform."""
    msgdef = schema.data.decode("utf-8", "replace") if schema is not None and schema.data else None

    def convert(data: bytes) -> list[bytes]:
        m = msg.decode_cdr(msg.TF_TYPE, data, msgdef)
        out = []
        for tr in m.transforms:
            stamp = tr.header.stamp
            r, t = tr.transform.rotation, tr.transform.translation
            out.append(msg.encode_frame_transform(stamp.sec + stamp.nanosec * 1e-9, (r.w, r.x, r.y, r.z),
                                                  child_frame_id=tr.child_frame_id,
                                                  parent_frame_id=tr.header.frame_id,
                                                  translation=(t.x, t.y, t.z)))
        return out

    return convert
