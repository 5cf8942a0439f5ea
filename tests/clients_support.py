"""Servers for the client and example tests: a site map run in a thread on an ephemeral
port under the manual clock, and the client-side map of it (the JSON export as a dict)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path

from motion_clients import ClientMap
from motion_server import config
from motion_server.tagmap import build_tagmap, to_dict
from tests.modbus_support import ServerThread

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "clients" / "examples" / "bench.toml"


class BenchServer(ServerThread):
    """A :class:`ServerThread` that waits longer for its start: the OPC UA front-end
    builds a large address space (and a certificate on first start) on a busy machine."""

    START_TIMEOUT = 60.0

    def __enter__(self) -> BenchServer:
        self._thread.start()
        if not self._ready.wait(self.START_TIMEOUT) or self._error is not None:
            raise RuntimeError(f"server did not start: {self._error!r}")
        return self


def manual_site(site: config.SiteMap, opcua: dict[str, object] | None = None) -> config.SiteMap:
    """``site`` with the manual clock, an ephemeral Modbus port and no status log; OPC UA
    off unless ``opcua`` gives its settings (then on an ephemeral port too)."""
    ctl = site.controller.model_copy(update={"clock": "manual", "status_log_interval": 0.0})
    modbus = site.modbus.model_copy(update={"port": 0, "host": "127.0.0.1"})
    ua = site.opcua.model_copy(
        update={"enabled": False} if opcua is None else {"port": 0, "enabled": True, **opcua}
    )
    return site.model_copy(update={"controller": ctl, "modbus": modbus, "opcua": ua})


def client_map(site: config.SiteMap) -> ClientMap:
    return ClientMap(to_dict(build_tagmap(site)))


@contextlib.contextmanager
def serving(site: config.SiteMap) -> Iterator[tuple[ServerThread, ClientMap]]:
    """``with serving(site) as (server, tagmap):`` — ``server.port`` is the bound port."""
    site = manual_site(site)
    with BenchServer(site) as srv:
        yield srv, client_map(site)
