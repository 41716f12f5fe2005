"""Zenoh configuration from the command line, as in Zenoh's own examples, with loopback defaults.

Flags (zenoh-python ``examples/common.py``): ``-m/--mode``, ``-e/--connect``, ``-l/--listen``,
``-c/--config``, ``--no-multicast-scouting``, plus ``--cfg KEY:VALUE`` for any other setting.

Without ``-c`` the session starts from a loopback peer configuration that needs no router: multicast and
gossip scouting off; a *producer* (``serve``, ``replay``) listens on ``tcp/127.0.0.1:7447`` and a *consumer*
(``record``) connects to it (a peer keeps retrying until the endpoint is up).
``service/peer-loopback.json5`` is the same configuration as a file.

Examples
--------
>>> import argparse, json
>>> p = argparse.ArgumentParser()
>>> add_config_arguments(p)
>>> args = p.parse_args(["-l", "tcp/127.0.0.1:7500", "--no-multicast-scouting"])
>>> conf = config_from_args(args, role="producer")
>>> json.loads(conf.get_json("listen/endpoints"))
['tcp/127.0.0.1:7500']
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import re
import socket

from ..errors import ConfigError

__all__ = [
    "DEFAULT_ENDPOINT",
    "ZenohSessionError",
    "ServiceConnectionError",
    "open_session",
    "zenoh_error",
    "describe_endpoints",
    "uses_default_endpoints",
    "add_config_arguments",
    "config_from_args",
    "loopback_config",
    "default_config_dict",
    "endpoint_problem",
    "check_endpoints",
]

#: Endpoint the default producer listens on and the default consumer connects to.
DEFAULT_ENDPOINT = "tcp/127.0.0.1:7447"


def default_config_dict(role: str = "producer", endpoint: str = DEFAULT_ENDPOINT) -> dict:
    """The loopback peer configuration as a dictionary (see module docstring).

    Parameters
    ----------
    role : {"producer", "consumer"}
        A producer listens on ``endpoint``; a consumer connects to it.
    endpoint : str
        Zenoh locator.
    """
    if role not in ("producer", "consumer"):
        raise ConfigError("role", role, "'producer' or 'consumer'")
    conf: dict = {
        "mode": "peer",
        "scouting": {"multicast": {"enabled": False}, "gossip": {"enabled": False}},
    }
    if role == "producer":
        conf["listen"] = {"endpoints": [endpoint]}
    else:
        conf["connect"] = {"endpoints": [endpoint]}
    return conf


def loopback_config(role: str = "producer", endpoint: str = DEFAULT_ENDPOINT, **overrides):
    """A ``zenoh.Config`` built from :func:`default_config_dict`; ``overrides`` map config paths to values.

    Examples
    --------
    >>> c = loopback_config("consumer", "tcp/127.0.0.1:7501")
    >>> c.get_json("connect/endpoints"), c.get_json("scouting/multicast/enabled")
    ('["tcp/127.0.0.1:7501"]', 'false')
    """
    import zenoh

    conf = zenoh.Config.from_json5(json.dumps(default_config_dict(role, endpoint)))
    for path, value in overrides.items():
        conf.insert_json5(path.replace("__", "/"), json.dumps(value))
    return conf


#: Zenoh's link protocols (zenoh-links: tcp, udp, tls, quic, ws, unixsock-stream, unixpipe, serial, vsock) and how
#: each writes its address: "host:port" (an IPv4 address, [an IPv6 address] or a host name, and a port 0..65535),
#: "path" (a socket file, a pipe, a serial device) or "cid:port" (a vsock context id and port).
ENDPOINT_PROTOCOLS = {"tcp": "host:port", "udp": "host:port", "tls": "host:port", "quic": "host:port",
                      "ws": "host:port", "unixsock-stream": "path", "unixpipe": "path", "serial": "path",
                      "vsock": "cid:port"}
_HOSTNAME = re.compile(r"^(?=.{1,253}$)[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?"
                       r"(?:\.[A-Za-z0-9](?:[A-Za-z0-9-]{0,61}[A-Za-z0-9])?)*\.?$")
_IPV4ISH = re.compile(r"^[0-9.]+$")


def _host_problem(host: str) -> str | None:
    import ipaddress

    if not host:
        return "no host before ':PORT' (e.g. 127.0.0.1, [::1] or localhost)"
    if host.startswith("["):
        if not host.endswith("]"):
            return f"the IPv6 address {host!r} lacks its closing ']'"
        try:
            ipaddress.IPv6Address(host[1:-1].split("%", 1)[0])
        except ValueError:
            return f"{host[1:-1]!r} is not an IPv6 address"
        return None
    if ":" in host:
        return f"an IPv6 address goes in brackets: [{host}]:PORT"
    if _IPV4ISH.match(host):
        try:
            ipaddress.IPv4Address(host)
        except ValueError:
            return f"{host!r} is not an IPv4 address"
        return None
    if not _HOSTNAME.match(host):
        return f"{host!r} is not a host name or an IP address"
    return None


def endpoint_problem(endpoint) -> str | None:
    """What is wrong with a Zenoh endpoint (``-e``, ``-l``, a config file's endpoints), or None: the forms Zenoh
    takes, ``<protocol>/<address>[?<metadata>][#<config>]`` with a protocol of :data:`ENDPOINT_PROTOCOLS` and an
    address as that protocol writes it (``tcp/127.0.0.1:7447``, ``udp/[::1]:7447``, ``tls/host.example:7447``,
    ``unixsock-stream//tmp/zenoh.sock``). Whether the address is reachable or free is Zenoh's to say when the
    session opens.

    >>> endpoint_problem("tcp/127.0.0.1:7447") is None, endpoint_problem("tcp/127.0.0.1")
    (True, 'tcp takes HOST:PORT and no port is given')
    """
    if not isinstance(endpoint, str):
        return "a text PROTOCOL/ADDRESS"
    proto, sep, rest = endpoint.partition("/")
    if not sep or not proto:
        return "it has no protocol before a '/'" if sep else "it has no '/' between a protocol and an address"
    form = ENDPOINT_PROTOCOLS.get(proto)
    if form is None:
        near = next((p for p in ENDPOINT_PROTOCOLS if p.lower() == proto.lower()), None)
        hint = f" (did you mean {near!r}?)" if near else ""
        return f"protocol {proto!r} is not one of Zenoh's ({', '.join(ENDPOINT_PROTOCOLS)}){hint}"
    address = rest.split("#", 1)[0].split("?", 1)[0]
    if not address.strip() or address != address.strip():
        return f"{proto} takes {form.upper()} and the address is empty or has blanks"
    if form == "path":
        return None
    if ":" not in address or (address.startswith("[") and not address.rsplit("]", 1)[-1].startswith(":")):
        return f"{proto} takes {form.upper()} and no port is given"
    host, _, port = address.rpartition(":")
    if not port.isdigit() or not 0 <= int(port) <= 65535:
        return f"the port {port!r} is not a number from 0 to 65535"
    if form == "cid:port":
        return None if host and re.match(r"^[\w-]+$", host) else f"{host!r} is not a vsock context id"
    problem = _host_problem(host)
    return problem


def check_endpoints(endpoints, flag: str) -> None:
    """Raise a :class:`ConfigError` (exit code 2) naming ``flag`` and the first malformed endpoint."""
    for ep in endpoints or ():
        problem = endpoint_problem(ep)
        if problem:
            raise ConfigError(flag, ep, f"a Zenoh endpoint PROTOCOL/ADDRESS (e.g. tcp/127.0.0.1:7447): {problem}")


def _zenoh_text(e: Exception) -> str:
    """Zenoh's error without its Rust wrappers and source locations: the message a user can act on."""
    raw = " ".join(str(e).split())
    m = re.search(r'msg: "(.*?)(?:\s+at\s+\S+\.rs:\d+(?::\d+)?)?\.?"', raw)
    text = m.group(1) if m else raw
    return _RUST_NOISE.sub("", text).strip().rstrip(".")


def _file_endpoint_error(path: str, e: Exception) -> ConfigError:
    """A config file Zenoh refuses: its bad endpoint named (exit code 2), else Zenoh's reason without internals."""
    text = _zenoh_text(e)
    m = re.search(r"Endpoints must be of the form .*?: (\S+)$", text)
    if m:
        ep = m.group(1)
        return ConfigError("-c/--config", path, f"a Zenoh JSON5 file whose endpoints are PROTOCOL/ADDRESS (e.g. "
                           f"tcp/127.0.0.1:7447); endpoint {ep!r}: {endpoint_problem(ep) or 'Zenoh refuses it'}")
    return ConfigError("-c/--config", path, f"a readable Zenoh JSON5 file; Zenoh says: {text}")


def add_config_arguments(parser: argparse.ArgumentParser) -> None:
    """Add Zenoh's example flags ``-m -e -l -c --no-multicast-scouting --cfg`` to ``parser``."""
    g = parser.add_argument_group("zenoh", "Zenoh session (as in Zenoh's examples); default: loopback peer")
    g.add_argument("--mode", "-m", dest="mode", choices=["peer", "client"], type=str,
                   help="The zenoh session mode.")
    g.add_argument("--connect", "-e", dest="connect", metavar="ENDPOINT", action="append", type=str,
                   help="Endpoints to connect to.")
    g.add_argument("--listen", "-l", dest="listen", metavar="ENDPOINT", action="append", type=str,
                   help="Endpoints to listen on.")
    g.add_argument("--config", "-c", dest="config", metavar="FILE", type=str,
                   help="A configuration file (JSON5); replaces the loopback default.")
    g.add_argument("--no-multicast-scouting", dest="no_multicast_scouting", default=False,
                   action="store_true", help="Disable multicast scouting.")
    g.add_argument("--cfg", dest="cfg", metavar="CFG", default=[], action="append", type=str,
                   help="Allows arbitrary configuration changes as column-separated KEY:VALUE pairs, where "
                        "KEY is a config path and VALUE a JSON5 value, "
                        "e.g. --cfg='transport/unicast/max_links:2'.")


def config_from_args(args: argparse.Namespace, role: str = "producer"):
    """Build the ``zenoh.Config`` of a command from its parsed flags.

    Starts from ``-c FILE`` or else the loopback default of ``role``; any ``-e`` or ``-l`` (or ``-m client``)
    replaces the default endpoints altogether (e.g. ``serve -e tcp/host:7447`` only connects);
    ``--no-multicast-scouting`` and ``--cfg`` are applied last.

    Raises
    ------
    ConfigError
        If the file cannot be read or a value is not accepted by Zenoh.
    """
    import zenoh

    connect = getattr(args, "connect", None)
    listen = getattr(args, "listen", None)
    mode = getattr(args, "mode", None)
    if getattr(args, "config", None):
        if not os.path.exists(args.config):
            raise ConfigError("-c/--config", args.config, "an existing Zenoh JSON5 file (not found)")
        try:
            conf = zenoh.Config.from_file(args.config)
        except Exception as e:  # zenoh.ZError: one clear line
            raise _file_endpoint_error(args.config, e) from None
        for key, flag in (("connect/endpoints", "-c/--config connect"), ("listen/endpoints", "-c/--config listen")):
            for ep in _endpoints(conf, key):
                if problem := endpoint_problem(ep):
                    raise ConfigError(flag, ep, f"a Zenoh endpoint PROTOCOL/ADDRESS (e.g. tcp/127.0.0.1:7447) in "
                                      f"{args.config}: {problem}")
    check_endpoints(connect, "-e/--connect")
    check_endpoints(listen, "-l/--listen")
    try:
        if not getattr(args, "config", None):
            d = default_config_dict(role)
            if connect is not None or listen is not None or mode == "client":
                # explicit endpoints replace the loopback default (no stray connection to 7447)
                d.pop("listen", None)
                d.pop("connect", None)
            conf = zenoh.Config.from_json5(json.dumps(d))
        if mode is not None:
            conf.insert_json5("mode", json.dumps(mode))
        if connect is not None:
            conf.insert_json5("connect/endpoints", json.dumps(connect))
        if listen is not None:
            conf.insert_json5("listen/endpoints", json.dumps(listen))
        if getattr(args, "no_multicast_scouting", False):
            conf.insert_json5("scouting/multicast/enabled", json.dumps(False))
        for c in getattr(args, "cfg", None) or []:
            key, sep, value = c.partition(":")
            if not sep:
                raise ConfigError("--cfg", c, "KEY:VALUE with a config path and a JSON5 value")
            try:
                conf.insert_json5(key, value)
            except Exception as e:  # noqa: BLE001 - zenoh.ZError: one clear line naming the setting
                raise ConfigError("--cfg", c, f"a config path and a JSON5 value Zenoh takes; Zenoh says: "
                                  f"{_zenoh_text(e)}") from None
            if key.strip("/").endswith("endpoints"):
                for ep in _endpoints(conf, key.strip("/")):
                    if problem := endpoint_problem(ep):
                        raise ConfigError("--cfg", c, f"Zenoh endpoints PROTOCOL/ADDRESS: {ep!r}: {problem}")
    except ConfigError:
        raise
    except Exception as e:  # zenoh.ZError: one clear line
        raise ConfigError("Zenoh flags", " ".join(f"{k}={v}" for k, v in (("mode", mode), ("connect", connect),
                                                                          ("listen", listen)) if v),
                          f"values Zenoh accepts; Zenoh says: {_zenoh_text(e)}") from None
    return conf


def uses_default_endpoints(args: argparse.Namespace) -> bool:
    """True when none of ``-c``, ``-e``, ``-l``, ``-m`` was given (the loopback default applies)."""
    return not any(getattr(args, a, None) for a in ("config", "connect", "listen", "mode"))


class ServiceConnectionError(ConnectionError):
    """A session or server of the service could not start or was lost (a port in use, a refused connection): a
    run-time failure, exit code 1 under :func:`gyrosim.errors.exit_code` (an ``OSError``, as a lost connection
    is; not a ``GyrosimError``, which ``exit_code`` maps to 2, the code of user errors)."""


class ZenohSessionError(ServiceConnectionError):
    """A Zenoh session could not start: one line naming the endpoint and the flag to change."""


_RUST_NOISE = re.compile(r"\s+at\s+\S+\.rs:\d+(:\d+)?\.?|\s*\(os error \d+\)")
_LOCATOR = re.compile(r"\b(?:tcp|udp|tls|quic|ws)/(?:\[[0-9a-fA-F:.%\w]+\]|[\w.\-]+):\d+")


def _endpoints(conf, path: str) -> list:
    """The endpoints a Zenoh config holds at ``path`` (``listen/endpoints``): a list, the per-mode lists of a dict
    ({"router": [...], "peer": [...]}) together, or one value as a list of one; [] where it is unset."""
    try:
        value = json.loads(conf.get_json(path))
    except Exception:  # noqa: BLE001 - an unset path
        return []
    if isinstance(value, dict):  # per-mode endpoints: {"router": [...], "peer": [...]}
        value = [e for v in value.values() for e in (v or [])]
    return list(value) if isinstance(value, list) else [] if value is None else [value]


def describe_endpoints(conf) -> str:
    """``"connecting to tcp/127.0.0.1:7447; listening on ..."``: a session's endpoints for a log line ("" if none).
    Per-mode endpoints count for the session's mode; a listener on port 0 (any free port) is not named."""
    try:
        mode = json.loads(conf.get_json("mode"))
    except Exception:  # noqa: BLE001 - an unset mode: Zenoh's default
        mode = "peer"
    parts = []
    for verb, path in (("connecting to", "connect/endpoints"), ("listening on", "listen/endpoints")):
        try:
            value = json.loads(conf.get_json(path))
        except Exception:  # noqa: BLE001 - an unset path
            value = []
        if isinstance(value, dict):
            value = value.get(mode) or []
        found = [str(e) for e in value or [] if not str(e).endswith(":0")]
        if found:
            parts.append(f"{verb} {', '.join(found)}")
    return "; ".join(parts)


def zenoh_error(e: Exception, conf=None) -> ZenohSessionError:
    """Translate a ``zenoh.ZError`` from opening a session into one line with the endpoint and the flag.

    Rust source locations and errno suffixes are dropped; a port in use, an address that is not local, a
    privileged port and a refused connection get their own hint.
    """
    raw = " ".join(str(e).split())
    text = _RUST_NOISE.sub("", raw).strip().rstrip(".")
    listen = _endpoints(conf, "listen/endpoints") if conf is not None else []
    connect = _endpoints(conf, "connect/endpoints") if conf is not None else []
    named = _LOCATOR.findall(raw)
    where = next((x for x in named if x in listen or x in connect), named[0] if named else None)
    low = raw.lower()
    if "address already in use" in low or "os error 98" in low or "addrinuse" in low:
        ep = where or (listen[0] if listen else "the listen endpoint")
        host = ep.split("/", 1)[-1].rsplit(":", 1)[0] if "/" in ep else "127.0.0.1"
        return ZenohSessionError(
            f"cannot listen on {ep}: the address is already in use (a running gyrosim serve or replay, or a "
            f"zenohd?); listen on another port with -l/--listen tcp/{host}:PORT, or connect to the one running "
            f"with -e/--connect {ep}")
    if "cannot assign requested address" in low or "os error 99" in low:
        ep = where or (listen[0] if listen else "the listen endpoint")
        return ZenohSessionError(f"cannot listen on {ep}: that address is not one of this host's; "
                                 "change -l/--listen")
    if "permission denied" in low or "os error 13" in low:
        ep = where or (listen[0] if listen else "the endpoint")
        return ZenohSessionError(f"cannot listen on {ep}: permission denied (ports below 1024 need "
                                 "privileges); change -l/--listen")
    ends = "; ".join(x for x in (f"listen {', '.join(listen)}" if listen else "",
                                 f"connect {', '.join(connect)}" if connect else "") if x)
    return ZenohSessionError(f"Zenoh session failed{f' ({ends})' if ends else ''}: {text}; check "
                             "-l/--listen, -e/--connect and -c/--config")


def _free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET) as s:
        s.bind((host.strip("[]"), 0))
        return s.getsockname()[1]


@contextlib.contextmanager
def open_session(conf, *, fallback_port: bool = False, log: logging.Logger | None = None):
    """``with open_session(conf) as session``: ``zenoh.open`` with errors as :class:`ZenohSessionError`.

    Parameters
    ----------
    conf : zenoh.Config
        Session configuration.
    fallback_port : bool
        If the (single TCP) listen endpoint is in use, listen on a free port of the same host instead and log
        a warning naming it (``replay`` does so by default, so it does not collide with a running ``serve``).
    log : logging.Logger, optional
        Where the warning goes (default ``gyrosim.service``).
    """
    import zenoh

    log = log or logging.getLogger("gyrosim.service")
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as e:
        err = zenoh_error(e, conf)
        listen = _endpoints(conf, "listen/endpoints")
        if not (fallback_port and "already in use" in str(err) and len(listen) == 1
                and listen[0].startswith("tcp/")):
            raise err from None
        host = listen[0][4:].rsplit(":", 1)[0]
        new = f"tcp/{host}:{_free_port(host)}"
        conf.insert_json5("listen/endpoints", json.dumps([new]))
        try:
            session = zenoh.open(conf)
        except zenoh.ZError as e2:
            raise zenoh_error(e2, conf) from None
        log.warning("%s is in use (a running gyrosim serve?); listening on %s instead: connect to it with "
                    "-e %s (or choose the port with -l)", listen[0], new, new)
    try:
        yield session
    finally:
        session.close()
