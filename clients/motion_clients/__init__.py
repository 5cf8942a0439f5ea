"""Tag-name clients for motion-server over Modbus TCP (and OPC UA): a library and a CLI.

::

    from motion_clients import ClientMap, MotionClient

    tagmap = ClientMap.load("maps/demo-map.json")      # or a site TOML, or None: the demo
    async with MotionClient.connect(tagmap, "modbus", "127.0.0.1", 5020) as mc:
        print(await mc.trigger("MSO_1", Axis=2))         # MSO_1: DN after 1 cycle(s)

Only the JSON map export ties the clients to the server: nothing here imports it.
"""

from .backend import BACKENDS, Backend, ClientError, ModbusBackend, make_backend
from .client import MotionClient, Outcome, TriggerTimeout
from .tagmap import ClientMap, MapError, MapTag, decode, encode
from .trace import Recorder, Trace

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
