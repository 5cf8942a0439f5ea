"""The web view's commands and trends over real sockets (docs/web.md § "Protocol"):
an operator's write and trigger seen over Modbus, an admin's clock step, a trend that
holds every cycle of a stepped run with the values Modbus reads for the same ticks, and
a gap counted, never hidden, when a client stops reading."""

from __future__ import annotations

import asyncio
import json
import socket
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from motion_server.testing import MotionServer
from tests.web_support import Http, next_text, parse_frame, users_map

#: the servo the demo map calls Slave (Axis2), jogged as examples/01_power_and_jog.py does
AXIS = 2
JOG = {
    "MAJ_1.Axis": AXIS,
    "MAJ_1.Direction": 0,
    "MAJ_1.Speed": 100.0,
    "MAJ_1.SpeedUnits": 0,
    "MAJ_1.AccelRate": 1000.0,
    "MAJ_1.AccelUnits": 0,
    "MAJ_1.DecelRate": 1000.0,
    "MAJ_1.DecelUnits": 0,
    "MAJ_1.Profile": 0,
}


@pytest.fixture
def server(tmp_path: Path) -> Iterator[MotionServer]:
    srv = MotionServer.start(tmp_path, users_map(tmp_path), clock="manual", opcua=False, web=True)
    try:
        yield srv
    finally:
        srv.finish()


def _jog(server: MotionServer, http: Http) -> None:
    """Servo on (over Modbus), then the jog's operands and trigger from the web view."""
    server.trigger("MSO_1", Axis=AXIS)
    status, body = http.post("/api/write", {"writes": JOG})
    assert status == 200 and set(body["results"].values()) == {"ok"}, body
    status, body = http.post("/api/trigger", {"instruction": "MAJ_1"})
    assert status == 200 and body["result"].startswith("ok"), body


def test_an_operator_jogs_from_the_web_and_modbus_sees_ip(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("otto")
    assert server.read("MAJ_1.IP") is False
    _jog(server, http)
    server.step(2)
    assert server.read("MAJ_1.IP") is True
    assert server.read("MAJ_1.Speed") == pytest.approx(100.0)
    audit = (server.workdir / "audit.jsonl").read_text("utf-8")
    web_lines = [json.loads(x) for x in audit.splitlines() if '"protocol":"web"' in x]
    assert any(r.get("tag") == "MAJ_1.Execute" and r["user"] == "otto" for r in web_lines)


def test_an_admin_steps_the_clock(server: MotionServer) -> None:
    http = Http(server.web_url)
    http.login("ada")
    before = int(server.read("Clock.Cycle"))
    status, body = http.post("/api/clock", {"action": "step", "cycles": 25})
    assert status == 200 and body["result"] == "ok", body
    assert int(server.read("Clock.Cycle")) == before + 25
    assert body["tick"] == before + 25
    assert http.post("/api/clock", {"action": "step", "cycles": 0})[0] == 400
    status, body = http.post("/api/snapshot", {"action": "save", "number": 5})
    assert status == 200 and body["result"] == "ok", body
    http.post("/api/clock", {"action": "step", "cycles": 10})
    status, body = http.post("/api/snapshot", {"action": "restore", "number": 5})
    assert status == 200 and body["result"] == "ok", body
    assert int(server.read("Clock.Cycle")) == before + 25  # the saved cycle is back
    assert http.post("/api/clock", {"action": "run"})[1]["result"] == "ok"
    assert server.read("Clock.Mode") == 0  # REALTIME: the map's manual mode is not "run"
    assert http.post("/api/clock", {"action": "pause"})[1]["result"] == "ok"
    assert server.read("Clock.Mode") == 1  # MANUAL
    assert http.post("/api/clock", {"action": "spin"})[0] == 400


async def test_a_trend_holds_every_cycle_with_the_values_modbus_reads(
    server: MotionServer,
) -> None:
    http = Http(server.web_url)
    http.login("otto")
    channels = [f"Axis{AXIS}.ActualPosition", f"Axis{AXIS}.CommandVelocity", "MAJ_1.IP"]
    rows: dict[int, np.ndarray] = {}
    async with http.connect() as ws:
        await ws.send(json.dumps({"type": "trend", "channels": channels}))
        await asyncio.to_thread(server.step, 1)  # the scan takes the set at its next cycle
        layout = await next_text(ws, "trend-layout")
        assert layout["channels"] == channels
        await asyncio.to_thread(_jog, server, http)
        seen: dict[int, float] = {}
        for chunk in (1, 7, 1, 50, 3):  # a Modbus client sees the last cycle of each step
            await asyncio.to_thread(server.step, chunk)
            values = await asyncio.to_thread(
                server.read_many, ["Clock.Cycle", f"Axis{AXIS}.ActualPosition"]
            )
            seen[int(values["Clock.Cycle"])] = float(values[f"Axis{AXIS}.ActualPosition"])
        last = max(seen)
        gaps = 0

        async def collect() -> None:
            nonlocal gaps
            while not rows or max(rows) < last:
                msg = await ws.recv()
                if isinstance(msg, bytes):
                    layout_id, gap, ticks, values = parse_frame(msg)
                    assert layout_id == layout["id"]
                    gaps += gap
                    for t, v in zip(ticks.tolist(), values, strict=True):
                        rows[t] = v

        await asyncio.wait_for(collect(), 20)
    first = min(rows)
    assert gaps == 0
    assert sorted(rows) == list(range(first, last + 1))  # every cycle, none twice
    for tick, position in seen.items():
        assert rows[tick][0] == position  # float64 both ways: equal, not close
    # the jog shows in the trend: IP rises, and the velocity ramps at 1000 mm/s² (2 mm/s
    # per 2 ms cycle) up to 100 mm/s
    ip = [rows[t][2] for t in sorted(rows)]
    assert ip[0] == 0.0 and ip[-1] == 1.0
    speeds = [rows[t][1] for t in sorted(rows)]
    assert max(speeds) == pytest.approx(100.0)
    steps = np.diff(speeds)
    assert steps.max() == pytest.approx(2.0)


async def test_a_client_that_stops_reading_is_told_the_gap(server: MotionServer) -> None:
    """The client stops reading while thousands of cycles run: frames are dropped for it,
    and the first frame after the stall counts exactly the ticks it did not get."""
    http = Http(server.web_url)
    http.login("otto")
    channels = [
        f"Axis{a}.{f}"
        for a in (1, 2, 3, 4)
        for f in ("ActualPosition", "CommandPosition", "ActualVelocity", "CommandVelocity")
    ]
    # a small receive window, set before connecting (it is fixed at the handshake)
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((http.host, http.port))
    async with http.connect(max_queue=1, ping_interval=None, sock=sock) as ws:
        await ws.send(json.dumps({"type": "trend", "channels": channels}))
        await asyncio.to_thread(server.step, 1)
        await next_text(ws, "trend-layout")
        # no reading now: 40,000 cycles of 16 channels are 5.4 MB of frames, more than
        # the socket buffers and the web process's queue for this client hold
        for _ in range(8):
            await asyncio.to_thread(server.step, 5000)
        last_tick: int | None = None
        reported = 0

        async def collect(until: int | None) -> None:
            """Read frames until tick ``until`` (None: until none came for 2 s)."""
            nonlocal last_tick, reported
            while until is None or last_tick != until:
                try:
                    msg = await asyncio.wait_for(ws.recv(), 2.0 if until is None else 30.0)
                except TimeoutError:
                    assert until is None
                    return
                if not isinstance(msg, bytes):
                    continue
                _, gap, ticks, _ = parse_frame(msg)
                if last_tick is not None:
                    assert gap == ticks[0] - last_tick - 1  # exactly the ticks not received
                reported += gap
                last_tick = int(ticks[-1])

        await collect(None)  # what the queue and the sockets held
        # the frames dropped during the stall are counted in the next frame that goes out
        await asyncio.to_thread(server.step, 10)
        await collect(int(await asyncio.to_thread(server.read, "Clock.Cycle")))
    assert reported > 0


def test_a_trigger_whose_tag_is_high_gives_a_new_edge_in_realtime(tmp_path: Path) -> None:
    """MSO_1 triggered for Axis1 leaves its Execute high; triggered again for Axis2 the
    web view must write it low, let a cycle scan it low, then high: a new rising edge."""
    server = MotionServer.start(
        tmp_path, users_map(tmp_path), clock="realtime", opcua=False, web=True
    )
    try:
        http = Http(server.web_url)
        http.login("otto")
        for axis in (1, 2):
            assert http.post("/api/write", {"writes": {"MSO_1.Axis": axis}})[0] == 200
            status, body = http.post("/api/trigger", {"instruction": "MSO_1"})
            assert status == 200 and body["result"] == "ok", body
            give_up = time.monotonic() + 10
            while int(server.read(f"Axis{axis}.AxisState")) != 2:  # 2 = Servo Control
                assert time.monotonic() < give_up, f"Axis{axis} not enabled"
                time.sleep(0.05)
    finally:
        server.finish()


async def test_a_trend_follows_the_controller_a_snapshot_restores(server: MotionServer) -> None:
    """A restore replaces the controller the scan runs: the trend then shows the restored
    one's values (its ring reads the new system), as Modbus does."""
    http = Http(server.web_url)
    http.login("ada")
    channel = f"Axis{AXIS}.CommandPosition"
    server.trigger("MSO_1", Axis=AXIS)
    http.post("/api/snapshot", {"action": "save", "number": 7})  # at rest
    _jog(server, http)
    server.step(100)
    rows: dict[int, float] = {}
    async with http.connect() as ws:
        await ws.send(json.dumps({"type": "trend", "channels": [channel]}))
        await asyncio.to_thread(server.step, 1)
        await next_text(ws, "trend-layout")
        status, body = http.post("/api/snapshot", {"action": "restore", "number": 7})
        assert status == 200 and body["result"] == "ok", body
        await asyncio.to_thread(server.step, 5)
        values = await asyncio.to_thread(server.read_many, ["Clock.Cycle", channel])
        tick, position = int(values["Clock.Cycle"]), float(values[channel])

        async def collect() -> None:
            while tick not in rows:
                msg = await ws.recv()
                if isinstance(msg, bytes):
                    _, _, ticks, vals = parse_frame(msg)
                    rows.update(zip(ticks.tolist(), vals[:, 0].tolist(), strict=True))

        await asyncio.wait_for(collect(), 20)
    assert rows[tick] == position  # the restored axis at rest, not the jog going on
