"""Tag-name clients for motion-server over Modbus TCP (and OPC UA): a library and a CLI.

::

    from motion_clients import ClientMap, MotionClient

    tagmap = ClientMap.load("maps/demo-map.json")      # or a site TOML, or None: the demo
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", 5020) as mc:
        print(await mc.trigger("MSO_1", Axis=2))         # MSO_1: DN after 1 cycle(s)

Only the JSON map export ties the clients to the server: nothing here imports it. The
register codec (:mod:`.codec`) goes the other way: the server imports it.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .backend import BACKENDS, Backend, ClientError, ModbusBackend, make_backend
    from .client import MotionClient, Outcome, TriggerTimeout
    from .tagmap import ClientMap, MapError, MapTag, decode, encode
    from .trace import Recorder, Trace

#: where each public name lives: imported when first used, so that ``motion_clients.codec``
#: (which the server's scan process imports) loads neither pymodbus nor asyncua
_HOMES = {
    "BACKENDS": "backend",
    "Backend": "backend",
    "ClientError": "backend",
    "ModbusBackend": "backend",
    "make_backend": "backend",
    "MotionClient": "client",
    "Outcome": "client",
    "TriggerTimeout": "client",
    "ClientMap": "tagmap",
    "MapError": "tagmap",
    "MapTag": "tagmap",
    "decode": "tagmap",
    "encode": "tagmap",
    "Recorder": "trace",
    "Trace": "trace",
}


#: submodules reachable as attributes of the package, as when it imported them all
_SUBMODULES = frozenset(
    {"backend", "cli", "client", "codec", "opcua", "plot", "scenario", "tagmap", "trace"}
)


def __getattr__(name: str) -> Any:
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{home}", __name__), name)
    globals()[name] = value
    return value


__version__ = "0.1.0"

__all__ = [
    "BACKENDS",
    "Backend",
    "ClientError",
    "ClientMap",
    "MapError",
    "MapTag",
    "ModbusBackend",
    "MotionClient",
    "Outcome",
    "Recorder",
    "Trace",
    "TriggerTimeout",
    "decode",
    "encode",
    "make_backend",
]
