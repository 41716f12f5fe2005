"""The Foxglove live view of ``gyrosim serve --foxglove [HOST:]PORT``: a Foxglove WebSocket server (the
``foxglove-sdk`` package) streaming what the service publishes on Zenoh.

Per body, on the topics of the MCAP recordings (``"/" + key``):

* ``.../state``: the same JSON ``gyrosim.BodyState`` bytes, with its JSON schema (Foxglove's rules);
* ``.../imu``: the same CDR ``sensor_msgs/msg/Imu`` bytes with the ``ros2msg`` definition;
* ``.../tf``: the transform parent -> body (``world`` -> body; in a tree scene from the parent body's frame, so
  the 3D panel draws the whole tree) as JSON ``foxglove.FrameTransform``, the schema Foxglove's 3D panel draws
  without any ROS support (the Zenoh key and the recordings keep CDR ``tf2_msgs/msg/TFMessage``).

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

    Raises
    ------
    GyrosimError
        If ``foxglove-sdk`` is not installed or the server cannot listen (one line with the address and the
        flag to change).
    """

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, name: str = "gyrosim", bodies=()):
        try:
            import foxglove
        except ImportError:
            raise GyrosimError("--foxglove needs the foxglove-sdk package: pip install 'gyrosim[service]'") from None
        self._foxglove = foxglove
        self.context = foxglove.Context()
        self._channels: dict[str, object] = {}
        for keys in bodies:
            self.add_body(keys)
        try:
            self.server = foxglove.start_server(name=name, host=host, port=int(port), context=self.context)
        except Exception as e:  # noqa: BLE001 - the SDK raises RuntimeError / its own errors
            why = " ".join(str(e).split())
            hint = ("the address is already in use" if "in use" in why.lower() or "os error 98" in why
                    else why)
            raise GyrosimError(f"cannot start the Foxglove WebSocket server on {host}:{port}: {hint}; choose "
                               "another with --foxglove HOST:PORT") from None
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
