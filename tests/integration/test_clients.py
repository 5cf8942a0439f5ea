"""The client library over a real socket: codec, map, trigger handshake, clock, errors.

Kinematics (first principles): a trapezoidal jog from rest to v = 10 mm/s at a = 100 mm/s²
reaches v after v/a = 0.1 s = 50 cycles of 2 ms, covering a·t²/2 = 0.5 mm; after k cycles
(t = 0.002·k s) it is at 50·t² mm while accelerating and 0.5 + 10·(t - 0.1) mm after.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_clients import ClientError, ClientMap, MapError, MotionClient, TriggerTimeout
from motion_clients import tagmap as client_codec
from motion_clients.plot import is_png, plot_trace
from motion_clients.trace import Recorder, Trace
from motion_server.kernel.errors import ERROR_TEXT, ErrorCode
from motion_server.tagmap import TagType, WordOrder
from motion_server.tagmap import decode as server_decode
from motion_server.tagmap import encode as server_encode
from tests.clients_support import ROOT, serving
from tests.modbus_support import ServerThread, modbus_site

DT = 0.002


def jog_position(cycles: int, v: float = 10.0, a: float = 100.0) -> float:
    t = cycles * DT
    if t <= v / a:
        return a * t * t / 2.0
    return v * v / (2.0 * a) + v * (t - v / a)


@pytest.fixture
def demo() -> Iterator[tuple[ServerThread, ClientMap]]:
    """Axis1 a virtual master, Axis2 a servo, Axis3 a hand wheel; MC_Power_1 on Axis2."""
    with serving(modbus_site()) as served:
        yield served


# -- codec and map ----------------------------------------------------------------------------
VALUES = {
    "SINT": [-128, -1, 0, 127],
    "INT": [-32768, -2, 0, 32767],
    "DINT": [-(2**31), -5, 0, 2**31 - 1],
    "UDINT": [0, 1, 2**16, 2**32 - 1],
    "REAL": [0.0, 0.1, -1.5, 3.0e38],
    "LREAL": [0.0, 0.1, -1e300, math.pi],
}


@pytest.mark.parametrize("order", ["big", "little"])
@pytest.mark.parametrize("type_name", sorted(VALUES))
def test_codec_agrees_with_the_servers_register_layout(order: str, type_name: str) -> None:
    words = {"SINT": 1, "INT": 1, "DINT": 2, "UDINT": 2, "REAL": 2, "LREAL": 4}[type_name]
    tag = client_codec.MapTag("X.Y", type_name, "read_write", 0, words, "X.Y")
    for value in VALUES[type_name]:
        regs = client_codec.encode(tag, value, order)
        assert regs == server_encode(TagType(type_name), value, WordOrder(order))
        back = client_codec.decode(tag, regs, order)
        assert back == server_decode(TagType(type_name), regs, WordOrder(order))


def test_map_from_the_checked_in_export_explains_error_codes() -> None:
    m = ClientMap.from_file(ROOT / "maps" / "demo-map.json")
    ratio = m.tag("MAG_1.Ratio")
    assert (ratio.type, ratio.address, ratio.count, ratio.access) == (
        "REAL",
        20914,
        2,
        "read_write",
    )
    assert m.tag("MAG_1.DN").bit == 1
    assert m.tag("MAG_1.Clutch").enum == {"ENABLED": 0, "DISABLED": 1}
    for code, text in ERROR_TEXT.items():
        assert m.error_text(int(code)) == text
    assert "not in the map" in m.error_text(4242)
    with pytest.raises(MapError, match="MAG_9"):
        m.tag("MAG_9.Ratio")
    with pytest.raises(MapError, match="SINT range"):
        m.tag("MAG_1.EXERR").coerce(300)
    assert m.tag("MAG_1.Direction").coerce("opposite") == 1


def test_map_by_running_motion_server_map_equals_the_export() -> None:
    from_server = ClientMap.load(None)
    from_file = ClientMap.load(ROOT / "maps" / "demo-map.json")
    assert [t for t in from_server] == [t for t in from_file]
    assert from_server.errors == from_file.errors


# -- trigger and clock --------------------------------------------------------------------------
async def test_trigger_power_and_jog_then_run_for(demo: tuple[ServerThread, ClientMap]) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        assert await mc.clock_mode() == "MANUAL"
        out = await mc.trigger("MSO_1", Axis=1)
        assert (out.ok, out.flag, out.code, out.cycles) == (True, "DN", 0, 1)
        assert await mc.read("MSO_1.Execute") is False  # lowered after DN
        jog = await mc.trigger(
            "MAJ_1", Axis=1, Direction="FORWARD", Speed=10.0, AccelRate=100.0, DecelRate=100.0
        )
        assert jog.ok and jog.cycles == 1
        assert await mc.read("Axis1.CommandPosition") == pytest.approx(jog_position(1), abs=1e-12)
        assert await mc.run_for(0.198) == 99  # 100 cycles of jog in all
        values = await mc.read_many(["Axis1.CommandPosition", "Axis1.CommandVelocity"])
        assert values["Axis1.CommandPosition"] == pytest.approx(1.5, abs=1e-9)
        assert values["Axis1.CommandVelocity"] == pytest.approx(10.0, abs=1e-9)
        assert await mc.cycle() == 1 + 1 + 99
        assert await mc.read("MAJ_1.IP") is True


async def test_trigger_reports_err_13_with_exerr_and_meaning(
    demo: tuple[ServerThread, ClientMap],
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        await mc.trigger("MSO_1", Axis=1)
        # MAM operands: Axis 0, MotionControl 1, MoveType 2, Position 3, Speed 4,
        # SpeedUnits 5, AccelRate 6
        out = await mc.trigger("MAM_1", Axis=1, MoveType=1, Position=5.0, Speed=10, AccelRate=-5)
        assert (out.ok, out.flag, out.code, out.exerr) == (False, "ER", 13, 6)
        assert out.meaning == ERROR_TEXT[ErrorCode.PARAMETER_OUT_OF_RANGE]
        assert "error 13" in str(out) and "EXERR 6" in str(out)
        await mc.step(20)
        assert await mc.read("Axis1.CommandPosition") == 0.0  # no motion


async def test_plcopen_trigger_waits_for_in_velocity_and_keeps_enable_high(
    demo: tuple[ServerThread, ClientMap],
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        power = await mc.trigger("MC_Power_1", Axis=2)
        assert (power.ok, power.flag) == (True, "Status")
        assert await mc.read("MC_Power_1.Enable") is True  # a level, not an edge
        # 10 mm/s at 100 mm/s²: the velocity is reached after 0.1 s = 50 cycles
        out = await mc.trigger(
            "MC_MoveVelocity_1", Axis=2, Velocity=10.0, Acceleration=100.0, Deceleration=100.0
        )
        assert (out.ok, out.flag, out.cycles) == (True, "InVelocity", 50)
        assert await mc.read("Axis2.CommandVelocity") == pytest.approx(10.0, abs=1e-9)
        assert await mc.read("Axis2.CommandPosition") == pytest.approx(0.5, abs=1e-9)
        # a refused block: Error and ErrorID with the meaning (axis 9 is not configured)
        bad = await mc.trigger("MC_Stop_1", Axis=9)
        assert (bad.ok, bad.flag, bad.code) == (False, "Error", int(ErrorCode.AXIS_NOT_CONFIGURED))
        assert bad.meaning == ERROR_TEXT[ErrorCode.AXIS_NOT_CONFIGURED]


async def test_back_to_back_triggers_of_one_instance_each_get_a_rising_edge(
    demo: tuple[ServerThread, ClientMap],
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        bad = await mc.trigger("MSO_1", Axis=9)
        assert (bad.ok, bad.code) == (False, int(ErrorCode.AXIS_NOT_CONFIGURED))
        # Execute was lowered after ER but not yet scanned low: the client runs that scan
        # first, or the server would see no edge and the stale ER would answer
        good = await mc.trigger("MSO_1", Axis=1)
        assert (good.ok, good.flag, good.cycles) == (True, "DN", 1)
        assert await mc.read("Axis1.AxisState") == 2


async def test_trigger_timeout_names_what_it_waited_for(
    demo: tuple[ServerThread, ClientMap],
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        await mc.trigger("MSO_1", Axis=1)
        before = await mc.cycle()
        with pytest.raises(TriggerTimeout, match=r"MAJ_1: no PC .* within 0.01 s \(simulated"):
            await mc.trigger("MAJ_1", until=("PC",), timeout=0.01, Axis=1, Speed=10.0)
        assert await mc.cycle() - before == 5  # 0.01 s of 2 ms cycles, then it gave up
        assert await mc.read("MAJ_1.Execute") is False
        with pytest.raises(ClientError, match="no output Bogus"):
            await mc.trigger("MAJ_1", until=("Bogus",))


async def test_writes_refused_by_the_server_or_the_map(
    demo: tuple[ServerThread, ClientMap],
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        with pytest.raises(ClientError, match="read-only"):
            await mc.write("MAJ_1.DN", True)
        with pytest.raises(MapError, match="not a REAL"):
            await mc.write("MAG_1.Ratio", "fast")
        await mc.write("MAG_1.Direction", "opposite")
        assert await mc.read("MAG_1.Direction") == 1
        # a value the tag holds but the server refuses: Clock.Mode 7 (Modbus exception 3)
        with pytest.raises(ClientError, match="refused"):
            await mc.write("Clock.Mode", 7)


async def test_little_word_order_reaches_the_server_as_written() -> None:
    site = modbus_site(word_order="little")
    with serving(site) as (srv, m):
        assert m.word_order == "little"
        async with MotionClient.connect(m, port=srv.port) as mc:
            await mc.write_many({"MAJ_1.Speed": 42.5, "MC_MoveAbsolute_1.Position": -1.25e-3})
            assert srv.runtime is not None
            assert srv.runtime.system["MAJ_1"].inputs["Speed"] == 42.5
            assert srv.runtime.system["MC_MoveAbsolute_1"].inputs["Position"] == -1.25e-3
            assert await mc.read("MAJ_1.Speed") == 42.5


async def test_recorder_trace_csv_and_plot(
    demo: tuple[ServerThread, ClientMap], tmp_path: Path
) -> None:
    srv, m = demo
    async with MotionClient.connect(m, port=srv.port) as mc:
        await mc.trigger("MSO_1", Axis=1)
        rec = Recorder(mc, ["Axis1.CommandPosition", "Axis1.CommandVelocity", "MAJ_1.IP"])
        start = await mc.cycle()
        jog = await mc.trigger("MAJ_1", Axis=1, Speed=10.0, AccelRate=100.0, DecelRate=100.0)
        await rec.sample()
        await rec.run(0.2, every=5)
    trace = Trace.read_csv(rec.trace.write_csv(tmp_path / "jog.csv"))
    assert trace.columns == rec.trace.columns and trace.rows == rec.trace.rows
    assert trace.units == {"Axis1.CommandPosition": "mm", "Axis1.CommandVelocity": "mm/s"}
    assert len(trace) == 1 + 20
    for cycle, time, pos in zip(
        trace.column("cycle"),
        trace.column("time"),
        trace.column("Axis1.CommandPosition"),
        strict=True,
    ):
        k = int(cycle) - start  # cycles since the jog's rising edge was scanned, plus one
        assert time == pytest.approx(cycle * DT, abs=1e-12)
        assert pos == pytest.approx(jog_position(k - jog.cycles + 1), abs=1e-9)
    assert set(trace.column("MAJ_1.IP")) == {1.0}
    png = plot_trace(trace, tmp_path / "jog.png", title="jog")
    assert is_png(png) and png.stat().st_size > 5000
    assert not is_png(tmp_path / "jog.csv")


def test_exported_errors_table_is_json_serialisable_and_complete() -> None:
    doc = json.loads((ROOT / "maps" / "demo-map.json").read_text("utf-8"))
    assert doc["errors"]["13"] == ERROR_TEXT[ErrorCode.PARAMETER_OUT_OF_RANGE]
    assert {int(k) for k in doc["errors"]} == {int(c) for c in ErrorCode}
