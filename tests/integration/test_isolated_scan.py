"""The scan in a process of its own, as ``motion-server run`` deploys it: what no client
can do to it, and what happens when a process dies.

Every test starts the real server (supervisor, scan, one process per front-end) in a
temporary directory and talks to it over loopback sockets.
"""

from __future__ import annotations

import asyncio
import json
import math
import signal
import socket
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from asyncua import Client, ua

from motion_clients import ClientMap, MotionClient
from motion_server import config
from motion_server.tagmap import TagType, build_tagmap, encode, to_dict
from tests.served import Served

SITE = """
[site]
name = "isolation"
namespace_uri = "urn:motion-server:isolation-test"

[controller]
clock = "realtime"
status_log_interval = 0.0

[modbus]
port = 0

[opcua]
port = 0
data_dir = "opcua-data"
allow_anonymous = true
anonymous_role = "operator"
allow_none_endpoint = true

[retain]
enabled = true
interval = 0.0
axes = ["Axis1"]

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1", "Wheel"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 1000.0

[[axes]]
name = "Wheel"
type = "feedback_only"
conversion_constant = 1000.0

[instructions]
every_type = true
"""
SPEED = 100.0  # mm/s


@pytest.fixture
def site_dir(tmp_path: Path) -> Path:
    (tmp_path / "site.toml").write_text(SITE)
    return tmp_path


@pytest.fixture
def client_map() -> ClientMap:
    return ClientMap(to_dict(build_tagmap(config.parse(SITE, "site.toml"))))


@pytest.fixture
def served(site_dir: Path) -> Iterator[Served]:
    with Served(site_dir, "site.toml") as srv:
        yield srv


async def jog(m: ClientMap, port: int) -> None:
    """Axis1 on and jogging at SPEED (reached after 100/5000 s)."""
    async with MotionClient.connect(m, port=port) as mc:
        assert (await mc.trigger("MSO_1", Axis=1)).ok
        jog = await mc.trigger(
            "MAJ_1", Axis=1, Speed=SPEED, AccelRate=5000.0, DecelRate=1000.0, AccelUnits=0
        )
        assert jog.ok, jog
        for _ in range(200):  # at speed after 0.02 s of acceleration
            if await mc.read("Axis1.CommandVelocity") == SPEED:
                return
            await asyncio.sleep(0.01)
        raise AssertionError("Axis1 does not reach its jog speed")


async def motion(m: ClientMap, protocol: str, port: int) -> tuple[int, float, float]:
    """(Clock.Cycle, Clock.SimTime, Axis1.ActualPosition) as a client reads them (with
    the clock running, the values may be of different cycles: see :func:`bracketed`)."""
    async with MotionClient.connect(m, protocol, port=port, security="None") as mc:
        v = await mc.read_many(["Clock.Cycle", "Clock.SimTime", "Axis1.ActualPosition"])
    return int(v["Clock.Cycle"]), float(v["Clock.SimTime"]), float(v["Axis1.ActualPosition"])


async def bracketed(m: ClientMap, protocol: str, port: int) -> tuple[int, float, float, float]:
    """(Clock.Cycle, SimTime read before, SimTime read after, Axis1.ActualPosition read in
    between), once the image this client sees shows Axis1 at SPEED (a front-end's image
    may lag the one another protocol showed). Each read sees the image of that moment and
    images only move forward, so the position is that of a simulated time between the
    two, however loaded the machine is."""
    async with MotionClient.connect(m, protocol, port=port, security="None") as mc:
        for _ in range(200):
            before = await mc.read_many(["Clock.Cycle", "Clock.SimTime", "Axis1.CommandVelocity"])
            if before["Axis1.CommandVelocity"] == SPEED:
                break
            await asyncio.sleep(0.01)
        else:
            raise AssertionError(f"{protocol}: Axis1 not at its jog speed")
        position = float(await mc.read("Axis1.ActualPosition"))
        after = float(await mc.read("Clock.SimTime"))
    return int(before["Clock.Cycle"]), float(before["Clock.SimTime"]), after, position


def jogged(first: tuple[int, float, float, float], then: tuple[int, float, float, float]) -> None:
    """The position moved at SPEED between two bracketed reads, both taken at speed
    (within float rounding of the published values)."""
    _, lo1, hi1, p1 = first
    _, lo2, hi2, p2 = then
    eps = 1e-3
    assert SPEED * (lo2 - hi1) - eps <= p2 - p1 <= SPEED * (hi2 - lo1) + eps, (first, then)


def wait_for(predicate: object, timeout: float, what: str) -> None:
    give_up = time.monotonic() + timeout
    while time.monotonic() < give_up:
        if predicate():  # type: ignore[operator]
            return
        time.sleep(0.1)
    raise AssertionError(f"not within {timeout} s: {what}")


def modbus_call(port: int, frame: bytes) -> bytes:
    with socket.create_connection(("127.0.0.1", port), timeout=5) as s:
        s.sendall(frame)
        return s.recv(256)


# -- what no client can do ------------------------------------------------------------------
def test_the_twelve_byte_frame_gets_an_exception_and_the_demo_server_stays_up(
    tmp_path: Path,
) -> None:
    """FC6 to the high word of Axis4.FeedbackInput: 0x7FE0 makes 8.98e307 mm, times 100
    counts/mm beyond float64: the write is refused (exception 03), nothing moves."""
    demo = build_tagmap(config.load())
    wheel = demo.tag("Axis4.FeedbackInput")
    assert wheel.address == 0x04A0  # the frame below is the one that ended the server
    with Served(tmp_path, opcua=False) as srv:
        before = modbus_call(srv.modbus_port, bytes.fromhex("000200000006010304a00004"))
        answer = modbus_call(srv.modbus_port, bytes.fromhex("000100000006010604a07fe0"))
        assert answer == bytes.fromhex("000100000003018603")  # FC6 exception 03
        time.sleep(0.2)  # cycles run; the scan would have died on the next one
        after = modbus_call(srv.modbus_port, bytes.fromhex("000200000006010304a00004"))
        assert after == before  # the hand wheel's input is unchanged
        actual = demo.tag("Axis4.ActualPosition")
        frame = struct.pack(">HHHBBHH", 3, 0, 6, 1, 3, actual.address, 4)
        regs = modbus_call(srv.modbus_port, frame)[9:]
        assert struct.unpack(">d", regs)[0] == 0.0  # nothing moved
        assert set(srv.children()) == {"scan", "modbus"}
        assert "Traceback" not in srv.log()


async def test_1e308_to_every_analog_input_is_refused_on_both_protocols(
    served: Served, client_map: ClientMap
) -> None:
    tagmap = build_tagmap(config.parse(SITE, "site.toml"))
    analog = [t for t in tagmap if t.writable and t.type.is_float]
    assert len(analog) > 40  # every REAL/LREAL operand of every instruction, the hand wheel
    # Modbus: FC16 of the value's registers (1e308 as REAL is infinity)
    refused = 0
    for k, tag in enumerate(analog):
        words = encode(tag.type, 1e308)
        pdu = struct.pack(
            f">BHHB{len(words)}H", 16, tag.address, len(words), 2 * len(words), *words
        )
        answer = modbus_call(served.modbus_port, struct.pack(">HHHB", k, 0, len(pdu) + 1, 1) + pdu)
        assert answer[7] == 0x90 and answer[8] == 3, (tag.name, answer.hex())
        refused += 1
    # OPC UA: Double 1e308 to LREAL nodes; a Float cannot hold 1e308: infinity to REAL nodes
    client = Client(served.endpoint, timeout=10)
    await client.connect()
    try:
        ns = await client.get_namespace_index("urn:motion-server:isolation-test")
        for tag in analog:
            if tag.type == TagType.LREAL:
                variant = ua.Variant(1e308, ua.VariantType.Double)
            else:
                variant = ua.Variant(math.inf, ua.VariantType.Float)
            node = client.get_node(ua.NodeId(tag.node_id, ns))
            with pytest.raises(ua.UaStatusCodeError) as err:
                await node.write_value(ua.DataValue(variant))
            assert err.value.code == ua.StatusCodes.BadOutOfRange, tag.name
        before = await motion(client_map, "opcua", served.opcua_port)
        time.sleep(0.3)
        after = await motion(client_map, "opcua", served.opcua_port)
    finally:
        await client.disconnect()
    assert after[0] > before[0]  # the scan runs on
    assert before[2] == after[2] == 0.0  # nothing moved
    assert "Traceback" not in served.log()
    assert refused == len(analog)


# -- processes that die ---------------------------------------------------------------------
async def test_a_killed_front_end_comes_back_while_motion_goes_on(
    served: Served, client_map: ClientMap
) -> None:
    m = client_map
    await jog(m, served.modbus_port)
    for role, other in (("modbus", "opcua"), ("opcua", "modbus")):
        offset = len(served.log())
        old = served.kill(role)
        port = served.modbus_port if other == "modbus" else served.opcua_port
        first = await bracketed(m, other, port)
        time.sleep(0.5)
        second = await bracketed(m, other, port)
        assert second[0] > first[0]  # cycles go on while the front-end is gone
        # jogging at SPEED: the position follows simulated time
        jogged(first, second)
        served.want_modbus, served.want_opcua = role == "modbus", role == "opcua"
        served.wait_serving(after=offset)
        new = served.children()[role]
        assert new != old
        # a client reconnects to the new process and reads a consistent image
        port = served.modbus_port if role == "modbus" else served.opcua_port
        third = await bracketed(m, role, port)
        assert third[0] > second[0] and third[1] > second[2]
        jogged(second, third)
    async with MotionClient.connect(m, port=served.modbus_port) as mc:
        assert await mc.read("Diagnostics.FrontendRestarts") == 2
    log = served.log()
    assert "the modbus front-end died (killed by SIGKILL)" in log
    assert "the opcua front-end died (killed by SIGKILL)" in log


async def test_sigterm_ends_in_the_programmed_stop(site_dir: Path, client_map: ClientMap) -> None:
    with Served(site_dir, "site.toml", opcua=False) as served:
        await jog(client_map, served.modbus_port)
        assert served.stop(signal.SIGTERM) == 0
        log = served.log()
    # 100 mm/s at 1000 mm/s²: 0.1 s of stop ramp, 50 cycles
    stop = [line for line in log.splitlines() if "programmed stop complete" in line]
    assert stop and "after 50 cycles" in stop[0], log[-2000:]
    retained = json.loads((site_dir / "retain.json").read_text())["payload"]
    assert retained["axes"]["Axis1"]["position"] > 0.0


async def test_a_dead_scan_stops_everything_and_leaves_the_retain_file(
    site_dir: Path, client_map: ClientMap
) -> None:
    with Served(site_dir, "site.toml", opcua=False) as srv:  # a clean run writes the retain file
        await jog(client_map, srv.modbus_port)
    retain_file = site_dir / "retain.json"
    assert retain_file.exists(), f"exit {srv.proc.returncode}\n{srv.log()[-3000:]}"
    saved = retain_file.read_bytes()
    with Served(site_dir, "site.toml", opcua=False) as srv:
        await jog(client_map, srv.modbus_port)  # Axis1 moves on from the retained position
        children = srv.children()
        srv.kill("scan")
        assert srv.proc is not None
        assert srv.proc.wait(30) == 1
        log = srv.log()
    died = [line for line in log.splitlines() if "scan process died" in line]
    assert len(died) == 1 and "killed by SIGKILL" in died[0]
    for pid in children.values():
        assert not Path(f"/proc/{pid}").exists() or _zombie(pid)
    assert retain_file.read_bytes() == saved  # not overwritten by anyone


def _zombie(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().split()[2] == "Z"
    except OSError:
        return True


def test_the_scan_process_imports_no_protocol_code() -> None:
    probe = (
        "import sys, motion_server.scan.process\n"
        "print([m for m in sys.modules if m.split('.')[0] in "
        "('pymodbus', 'asyncua', 'asyncio', 'cryptography')])"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
