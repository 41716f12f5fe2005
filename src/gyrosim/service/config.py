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
import json

from ..errors import ConfigError

__all__ = [
    "DEFAULT_ENDPOINT",
    "add_config_arguments",
    "config_from_args",
    "loopback_config",
    "default_config_dict",
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
        try:
            conf = zenoh.Config.from_file(args.config)
        except Exception as e:  # zenoh.ZError: one clear line
            raise ConfigError("-c/--config", args.config, f"a readable Zenoh JSON5 file; Zenoh says: {e}") from None
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
            conf.insert_json5(key, value)
    except ConfigError:
        raise
    except Exception as e:  # zenoh.ZError: one clear line
        raise ConfigError("Zenoh flags", " ".join(f"{k}={v}" for k, v in (("mode", mode), ("connect", connect),
                                                                          ("listen", listen)) if v),
                          f"values Zenoh accepts; Zenoh says: {e}") from None
    return conf
