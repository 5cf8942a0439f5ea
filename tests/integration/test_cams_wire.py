"""The cam instructions over real sockets (127.0.0.1, ephemeral ports, manual clock).

A client writes a cam table's points (Modbus FC16 to the documented registers, or OPC UA
through the array views), triggers MCCP, then MAPC (Logix) or MC_CamTableSelect and
MC_CamIn (PLCopen), steps the clock and reads the slave's CommandPosition, the
MotionStatus bits (8 PositionCamStatus, 13 PositionCamLockStatus), the instruction's
status and the table's ProfileStatus (0 not calculated, 2 calculated, 2 + n in use by n
cams). Triggers go through the project's client (``motion_clients.MotionClient``); one
case drives everything with pyModbusTCP, a client that is not ours.

Numbers from first principles:

- Register addresses (docs/modbus.md): the first table at the cam base 30000, a block of
  8 + 6·capacity registers rounded up to a multiple of 100 (capacity 4: 32 registers, so
  the tables sit at 30000, 30100, 30200); in a table at base B, Length at B+6, element
  k's Master at B+8+6k, Slave at B+10+6k, SegmentType at B+12+6k.
- A trapezoidal jog from rest at 100 mm/s with 1000 mm/s² is at 500·t² mm while it
  accelerates (t ≤ 0.1 s) and at 5 + 100·(t − 0.1) mm once at speed; t = 0.002 s per cycle.
- Table ``Lin`` (linear): (0, 0), (100, 50), (200, 150): f(m) = m/2 up to 100, then
  50 + (m − 100). MAPC is incremental: slave = slave at lock + f(m − m at lock).
- Table ``Cub`` (cubic, a clamped spline with slopes 0 at both ends): (0, 0), (90, 45),
  (180, 180). The slope at the middle point solves
  h·m0 + 2(h + h)·m1 + h·m2 = 3(h·d0 + h·d1) with h = 90, d0 = 1/2, d1 = 3/2, m0 = m2 = 0:
  m1 = 3/2. With the Hermite basis at the middle of a segment (h00 = h01 = 1/2,
  h10 = 1/8, h11 = −1/8): f(45) = 45/2 − 90·(3/2)/8 = 5.625 and
  f(135) = 45/2 + 90·(3/2)/8 + 180/2 = 129.375; a Continuous pass adds f(180) = 180.
- Table ``Shear`` (linear, periodic for MC_CamIn): (0, 0), (50, 25), (100, 100): slope
  1/2, then 3/2; each period of 100 adds 100.
"""

from __future__ import annotations

import struct
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from asyncua import Client, ua
from pymodbus.client import AsyncModbusTcpClient
from pyModbusTCP.client import ModbusClient

from motion_clients import ClientMap, MotionClient
from motion_clients.tagmap import decode, encode
from motion_server import config
from motion_server.kernel import MotionStatusBit
from tests.clients_support import BenchServer, client_map
from tests.opcua_support import USERS, secure_client, user_hashes

DT = 0.002
PC8 = 1 << MotionStatusBit.POSITION_CAM
LOCK13 = 1 << MotionStatusBit.POSITION_CAM_LOCK

SITE = """
[site]
name = "cams_wire"
namespace_uri = "urn:motion-server:cams-wire"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
port = 0
host = "127.0.0.1"

# the tests step the clock over plain Modbus: with OPC UA users on the map, plain clients
# are operators unless the map grants more
[modbus.access]
role = "admin"

[opcua]
enabled = {opcua}
port = 0
data_dir = "{data_dir}"
{users}

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Master", "Slave", "Wheel", "Slave2", "PMaster", "PSlave"]

[[axes]]
name = "Master"          # Axis1: a virtual master that jogs
type = "virtual"
max_velocity = 1000.0
max_acceleration = 10000.0
max_deceleration = 10000.0

[[axes]]
name = "Slave"           # Axis2
type = "servo"
max_velocity = 5000.0
max_acceleration = 100000.0
max_deceleration = 100000.0

[[axes]]
name = "Wheel"           # Axis3: a hand wheel, position written to FeedbackInput
type = "feedback_only"
feedback_signal = "input"

[[axes]]
name = "Slave2"          # Axis4
type = "servo"
max_velocity = 5000.0
max_acceleration = 100000.0
max_deceleration = 100000.0

[[axes]]
name = "PMaster"         # Axis5: PLCopen master
type = "virtual"
max_velocity = 1000.0
max_acceleration = 10000.0
max_deceleration = 10000.0

[[axes]]
name = "PSlave"          # Axis6: PLCopen slave
type = "servo"
max_velocity = 5000.0
max_acceleration = 100000.0
max_deceleration = 100000.0

[[cams]]
name = "Lin"             # table 1, written over Modbus
capacity = 4

[[cams]]
name = "Cub"             # table 2, written over OPC UA
capacity = 4

[[cams]]
name = "Shear"           # table 3, for MC_CamTableSelect
capacity = 4

[instructions]
every_type = true

[[instructions.instances]]
name = "Power_PMaster"
type = "MC_Power"
operands = {{ Axis = 5 }}

[[instructions.instances]]
name = "Power_PSlave"
type = "MC_Power"
operands = {{ Axis = 6 }}
"""

LIN, CUB, SHEAR = 30000, 30100, 30200  # the tables' blocks (see the module docstring)


def site_map(tmp: Path, opcua: bool) -> config.SiteMap:
    hashes = user_hashes()
    users = "\n".join(
        f'[[opcua.users]]\nname = "{name}"\nrole = "{USERS[name][0]}"\npassword_hash = "{h}"\n'
        for name, h in hashes.items()
    )
    text = SITE.format(opcua=str(opcua).lower(), data_dir=tmp / "opcua-data", users=users)
    return config.parse(text, "cams-wire.toml")


def regs(fmt: str, *values: float) -> list[int]:
    """Big-endian registers (the default word order) of REAL ('f') and DINT ('i') values."""
    data = struct.pack(">" + fmt, *values)
    return [int.from_bytes(data[i : i + 2], "big") for i in range(0, len(data), 2)]


def jog(cycles: int, v: float = 100.0, a: float = 1000.0) -> float:
    """A trapezoidal jog's position ``cycles`` cycles after it started from rest."""
    t = cycles * DT
    return a * t * t / 2.0 if t <= v / a else v * v / (2.0 * a) + v * (t - v / a)


def lin(m: float) -> float:
    """Table Lin: slope 1/2 up to 100, then 1 up to 200."""
    return m / 2.0 if m <= 100.0 else 50.0 + (m - 100.0)


class Served:
    def __init__(self, srv: BenchServer, tagmap: ClientMap, tmp: Path) -> None:
        self.srv = srv
        self.map = tagmap
        self.tmp = tmp

    @property
    def modbus_port(self) -> int:
        return self.srv.port

    @property
    def opcua_port(self) -> int:
        rt = self.srv.runtime
        assert rt is not None and rt.opcua is not None
        return rt.opcua.port

    def modbus(self) -> MotionClient:
        return MotionClient.connect(self.map, "modbus", port=self.modbus_port)

    def opcua(self, user: str = "admin") -> MotionClient:
        return MotionClient.connect(
            self.map,
            "opcua",
            port=self.opcua_port,
            user=user,
            password=USERS[user][1],
            cert_dir=self.tmp / "client",
        )


@pytest.fixture(scope="module")
def served(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Served]:
    tmp = tmp_path_factory.mktemp("cams-wire")
    site = site_map(tmp, opcua=True)
    with BenchServer(site) as srv:
        yield Served(srv, client_map(site), tmp)


async def motion_status(mc: MotionClient, axis: str) -> int:
    return int(await mc.read(f"{axis}.MotionStatus"))


# -- Logix over Modbus: FC16, MCCP, MAPC Once on a jogging master ------------------------------
async def test_mapc_once_on_a_jogging_master_over_modbus(served: Served) -> None:
    m = served.map
    # the documented registers, as the client's map has them too
    assert m.tag("Lin.Length").address == LIN + 6
    assert m.tag("Lin.Master[2]").address == LIN + 8 + 12
    assert m.tag("Lin.Slave[2]").address == LIN + 10 + 12
    assert m.tag("Lin.SegmentType[2]").address == LIN + 12 + 12
    raw = AsyncModbusTcpClient("127.0.0.1", port=served.modbus_port, timeout=5)
    assert await raw.connect()
    try:
        # three whole points in one FC16: (0, 0, linear), (100, 50, linear), (200, 150, linear)
        points = regs("ffiffiffi", 0.0, 0.0, 0, 100.0, 50.0, 0, 200.0, 150.0, 0)
        assert not (await raw.write_registers(LIN + 8, points)).isError()
    finally:
        raw.close()
    async with served.modbus() as mc:
        assert await mc.read("Lin.ProfileStatus") == 0  # not calculated
        assert (await mc.trigger("MSO_1", Axis=1)).ok
        assert (await mc.trigger("MSO_1", Axis=2)).ok
        mccp = await mc.trigger(
            "MCCP_1", Cam=1, Length=3, StartSlope=0.0, EndSlope=0.0, CamProfile=1
        )
        assert mccp.ok and mccp.cycles == 1  # one scan
        assert await mc.read("Lin.ProfileStatus") == 2  # calculated
        assert [await mc.read(f"Lin.Slave[{k}]") for k in range(3)] == [0.0, 50.0, 150.0]
        mapc = await mc.trigger(
            "MAPC_1",
            SlaveAxis=2,
            MasterAxis=1,
            CamProfile=1,
            ExecutionMode="ONCE",
            ExecutionSchedule="IMMEDIATE",
            MasterReference="COMMAND",
        )
        assert mapc.ok and mapc.cycles == 1
        got = await mc.read_many(["MAPC_1.DN", "MAPC_1.IP", "MAPC_1.PC", "MAPC_1.SEGMENT"])
        assert got == {
            "MAPC_1.DN": True,
            "MAPC_1.IP": True,
            "MAPC_1.PC": False,
            "MAPC_1.SEGMENT": 0,
        }
        assert await motion_status(mc, "Slave") & (PC8 | LOCK13) == PC8 | LOCK13
        assert await mc.read("Lin.ProfileStatus") == 3  # in use by one cam
        m0 = float(await mc.read("Master.CommandPosition"))
        s0 = float(await mc.read("Slave.CommandPosition"))
        jog_ = await mc.trigger("MAJ_1", Axis=1, Speed=100.0, AccelRate=1000.0, DecelRate=1000.0)
        assert jog_.ok and jog_.cycles == 1
        n = 1
        for until, segment in ((25, 0), (250, 0), (600, 1), (1000, 1)):
            await mc.step(until - n)
            n = until
            master = float(await mc.read("Master.CommandPosition"))
            assert master - m0 == pytest.approx(jog(n), abs=1e-9)
            slave = float(await mc.read("Slave.CommandPosition"))
            assert slave - s0 == pytest.approx(lin(jog(n)), abs=1e-9)
            assert await mc.read("MAPC_1.SEGMENT") == segment
            assert await mc.read("MAPC_1.IP") is True
        # the master leaves the profile at 200 mm (t = 2.05 s, cycle 1025): PC, IP cleared,
        # the cam bits cleared, the slave stays at f(200) = 150
        await mc.step(1030 - n)
        got = await mc.read_many(["MAPC_1.DN", "MAPC_1.IP", "MAPC_1.PC"])
        assert got == {"MAPC_1.DN": True, "MAPC_1.IP": False, "MAPC_1.PC": True}
        assert float(await mc.read("Slave.CommandPosition")) - s0 == 150.0
        assert await motion_status(mc, "Slave") & (PC8 | LOCK13) == 0
        assert await mc.read("Lin.ProfileStatus") == 2
        assert (await mc.trigger("MAS_1", Axis=1)).ok


# -- Logix over OPC UA: the array views, MCCP, MAPC Continuous on a hand wheel ---------------
def write_view(client: Client, ns: int, node: str, value: list[Any], vt: ua.VariantType) -> Any:
    wv = ua.WriteValue(
        NodeId=ua.NodeId(node, ns),
        AttributeId=ua.AttributeIds.Value,
        Value=ua.DataValue(ua.Variant(value, vt)),
    )
    return client.uaclient.write(ua.WriteParameters(NodesToWrite=[wv]))


async def wheel_to(mc: MotionClient, position: float) -> tuple[float, float]:
    """Turn the hand wheel to ``position``; (its actual position, Slave2's command)."""
    await mc.write("Wheel.FeedbackInput", position)
    await mc.step(2)
    got = await mc.read_many(["Wheel.ActualPosition", "Slave2.CommandPosition"])
    return float(got["Wheel.ActualPosition"]), float(got["Slave2.CommandPosition"])


async def test_mapc_continuous_on_a_hand_wheel_over_opcua(served: Served) -> None:
    rt = served.srv.runtime
    assert rt is not None
    # the operator writes the table's points through the array views (capacity 4: the
    # fourth element stays as it is, MCCP uses the first three)
    operator = await secure_client(rt, served.tmp / "operator", "operator", "run-the-line")
    async with operator:
        ns = await operator.get_namespace_index(served.map.namespace_uri)
        f, i = ua.VariantType.Float, ua.VariantType.Int32
        for node, values, vt in (
            ("Cams.Cub.MasterValues", [0.0, 90.0, 180.0, 270.0], f),
            ("Cams.Cub.SlaveValues", [0.0, 45.0, 180.0, 0.0], f),
            ("Cams.Cub.SegmentTypes", [1, 1, 1, 0], i),
        ):
            [code] = await write_view(operator, ns, node, values, vt)
            assert code.is_good(), (node, code)
    async with served.opcua() as mc:
        assert await mc.read("Cub.ProfileStatus") == 0
        assert (await mc.trigger("MSO_1", Axis=4)).ok
        await wheel_to(mc, 0.0)
        assert (await mc.trigger("MCCP_1", Cam=2, Length=3, CamProfile=2)).ok
        assert await mc.read("Cub.ProfileStatus") == 2
        mapc = await mc.trigger(
            "MAPC_1",
            SlaveAxis=4,
            MasterAxis=3,
            CamProfile=2,
            ExecutionMode="CONTINUOUS",
            ExecutionSchedule="IMMEDIATE",
            MasterReference="ACTUAL",
        )
        assert mapc.ok
        assert (await mc.read("MAPC_1.IP"), await mc.read("MAPC_1.PC")) == (True, False)
        assert await motion_status(mc, "Slave2") & (PC8 | LOCK13) == PC8 | LOCK13
        assert await mc.read("Cub.ProfileStatus") == 3
        s0 = float(await mc.read("Slave2.CommandPosition"))
        # the spline's worked values (module docstring); a pass adds f(180) = 180, both ways
        for wheel, expected, segment in (
            (45.0, 5.625, 0),
            (135.0, 129.375, 1),
            (180.0 + 45.0, 180.0 + 5.625, 0),
            (180.0 + 135.0, 180.0 + 129.375, 1),
            (45.0, 5.625, 0),
            (-45.0, 129.375 - 180.0, 1),
        ):
            actual, slave = await wheel_to(mc, wheel)
            assert actual == wheel
            assert slave - s0 == pytest.approx(expected, abs=1e-9)
            assert await mc.read("MAPC_1.SEGMENT") == segment
            assert await motion_status(mc, "Slave2") & LOCK13
        # MAS Position Cam ends it: IP and both bits cleared, the profile free again
        assert (await mc.trigger("MAS_1", Axis=4, StopType="POSITION_CAM")).ok
        await mc.step(1)
        assert await mc.read("MAPC_1.IP") is False
        assert await motion_status(mc, "Slave2") & (PC8 | LOCK13) == 0
        assert await mc.read("Cub.ProfileStatus") == 2


# -- PLCopen over Modbus: MC_CamTableSelect, MC_CamIn, EndOfProfile, MC_CamOut ---------------
def shear(m: float) -> float:
    """Table Shear, periodic: slope 1/2 to 50, 3/2 to 100, each period adds 100."""
    k, x = divmod(m, 100.0)
    return 100.0 * k + (x / 2.0 if x <= 50.0 else 25.0 + 1.5 * (x - 50.0))


async def test_mc_camin_periodic_then_camout_over_modbus(served: Served) -> None:
    async with served.modbus() as mc:
        for k, (master, slave) in enumerate(((0.0, 0.0), (50.0, 25.0), (100.0, 100.0))):
            await mc.write(f"Shear.Master[{k}]", master)
            await mc.write(f"Shear.Slave[{k}]", slave)
            await mc.write(f"Shear.SegmentType[{k}]", 0)
        await mc.write("Shear.Length", 3)
        assert (await mc.trigger("Power_PMaster", Enable=True)).ok
        assert (await mc.trigger("Power_PSlave", Enable=True)).ok
        select = await mc.trigger(
            "MC_CamTableSelect_1",
            Master=5,
            Slave=6,
            CamTable=3,
            Periodic=True,
            MasterAbsolute=True,
            SlaveAbsolute=True,
        )
        assert select.ok and select.cycles == 1
        table_id = int(await mc.read("MC_CamTableSelect_1.CamTableID"))
        assert table_id >= 1
        assert await mc.read("Shear.ProfileStatus") == 2
        # both axes at 0: the absolute cam puts the slave at f(0) = 0, in sync at once
        cam = await mc.trigger(
            "MC_CamIn_1", Master=5, Slave=6, CamTableID=table_id, MasterValueSource="SET_VALUE"
        )
        assert cam.ok and cam.flag == "InSync" and cam.cycles == 1
        assert await mc.read("PSlave.PLCopenState") == 8  # SynchronizedMotion
        assert await mc.read("Shear.ProfileStatus") == 3
        vel = await mc.trigger(
            "MC_MoveVelocity_1",
            Axis=5,
            Velocity=200.0,
            Acceleration=10000.0,
            Deceleration=10000.0,
        )
        assert vel.ok  # InVelocity: 200 / 10000 = 0.02 s
        # 0.4 mm per cycle at speed: every cycle, the slave on the cam and one pulse per
        # period, in the cycle the master passes 100, 200
        pulses: list[float] = []
        names = [
            "PMaster.CommandPosition",
            "PSlave.CommandPosition",
            "MC_CamIn_1.EndOfProfile",
            "MC_CamIn_1.InSync",
            "MC_CamIn_1.Busy",
        ]
        prev = float(await mc.read("PMaster.CommandPosition"))
        while prev < 230.0:
            await mc.step(1)
            got = await mc.read_many(names)
            master = float(got["PMaster.CommandPosition"])
            assert float(got["PSlave.CommandPosition"]) == pytest.approx(shear(master), abs=1e-9)
            assert got["MC_CamIn_1.InSync"] is True and got["MC_CamIn_1.Busy"] is True
            crossed = int(master // 100.0) > int(prev // 100.0)
            assert got["MC_CamIn_1.EndOfProfile"] is crossed, (prev, master)
            if crossed:
                pulses.append(master)
            prev = master
        assert len(pulses) == 2
        # in the 3/2 section (master 250..300): the slave at 1.5 · 200 = 300 mm/s
        await mc.step(round((275.0 - prev) / 0.4))
        assert await mc.read("PSlave.CommandVelocity") == pytest.approx(300.0, abs=1e-9)
        out = await mc.trigger("MC_CamOut_1", Slave=6)
        assert out.ok
        assert await mc.read("MC_CamIn_1.CommandAborted") is True
        assert await mc.read("Shear.ProfileStatus") == 2
        # the slave keeps the cam's last velocity (ContinuousMotion) while the master,
        # past 300, is back in the slope-1/2 section
        await mc.step(100)
        assert await mc.read("PSlave.CommandVelocity") == pytest.approx(300.0, abs=1e-9)
        assert await mc.read("PSlave.PLCopenState") == 7
        stop = await mc.trigger("MC_Stop_1", Axis=6, Deceleration=100000.0)
        assert stop.ok
        assert await mc.read("PSlave.CommandVelocity") == 0.0
        await mc.step(1)  # Stopping until a scan sees Execute low, then StandStill
        assert await mc.read("PSlave.PLCopenState") == 2
        assert (await mc.trigger("MC_Stop_1", Axis=5, Deceleration=10000.0)).ok


# -- a client that is not ours: pyModbusTCP writes the table and drives MCCP and MAPC --------
class Tags:
    """Tag access with pyModbusTCP through the server's own map (as the interop tests)."""

    def __init__(self, client: ModbusClient, tagmap: ClientMap) -> None:
        self.c = client
        self.map = tagmap

    def read(self, name: str) -> Any:
        tag = self.map.tag(name)
        words = self.c.read_holding_registers(tag.address, tag.count)
        assert words is not None, f"{name}: {self.c.last_except_as_txt}"
        if tag.type == "BOOL":
            return bool(words[0] >> (tag.bit or 0) & 1)
        return decode(tag, words)

    def write(self, name: str, value: float) -> None:
        tag = self.map.tag(name)
        if tag.type == "BOOL":  # read-modify-write of the command bits register
            reg = self.c.read_holding_registers(tag.address, 1)
            assert reg is not None
            bit = 1 << (tag.bit or 0)
            ok = self.c.write_single_register(
                tag.address, (reg[0] | bit) if value else (reg[0] & ~bit)
            )
        else:
            ok = self.c.write_multiple_registers(tag.address, encode(tag, tag.coerce(value)))
        assert ok, f"{name}: {self.c.last_except_as_txt}"

    def step(self, cycles: int) -> None:
        self.write("Clock.StepCycles", cycles)
        self.write("Clock.Step", False)
        self.write("Clock.Step", True)

    def trigger(self, instance: str, **operands: float) -> None:
        for name, value in operands.items():
            self.write(f"{instance}.{name}", value)
        self.write(f"{instance}.Execute", False)
        self.step(1)
        self.write(f"{instance}.Execute", True)
        self.step(1)


def test_pymodbustcp_writes_a_table_and_runs_mapc_once_on_a_hand_wheel(
    tmp_path: Path,
) -> None:
    site = site_map(tmp_path, opcua=False)
    with BenchServer(site) as srv:
        c = ModbusClient(host="127.0.0.1", port=srv.port, unit_id=1, timeout=5.0)
        t = Tags(c, client_map(site))
        try:
            # FC16 with the documented addresses: (0, 0), (100, 50), (200, 150), linear
            points = regs("ffiffiffi", 0.0, 0.0, 0, 100.0, 50.0, 0, 200.0, 150.0, 0)
            assert c.write_multiple_registers(LIN + 8, points)
            assert c.read_holding_registers(LIN + 8, 18) == points
            assert t.read("Lin.ProfileStatus") == 0
            t.trigger("MSO_1", Axis=4)
            t.trigger("MCCP_1", Cam=1, Length=3, CamProfile=1)
            assert (t.read("MCCP_1.DN"), t.read("MCCP_1.ER")) == (True, False)
            assert t.read("Lin.ProfileStatus") == 2
            t.trigger(
                "MAPC_1",
                SlaveAxis=4,
                MasterAxis=3,
                CamProfile=1,
                ExecutionMode=0,
                ExecutionSchedule=0,
                MasterReference=0,
            )
            assert (t.read("MAPC_1.DN"), t.read("MAPC_1.IP")) == (True, True)
            status = t.read("Slave2.MotionStatus")
            assert status & (PC8 | LOCK13) == PC8 | LOCK13
            s0 = t.read("Slave2.CommandPosition")
            for wheel, expected in ((50.0, 25.0), (150.0, 100.0), (199.5, 149.5)):
                t.write("Wheel.FeedbackInput", wheel)
                t.step(2)
                assert t.read("Slave2.CommandPosition") - s0 == expected
                assert t.read("MAPC_1.PC") is False
            t.write("Wheel.FeedbackInput", 250.0)  # beyond the profile: the cam completes
            t.step(2)
            assert (t.read("MAPC_1.IP"), t.read("MAPC_1.PC")) == (False, True)
            assert t.read("Slave2.CommandPosition") - s0 == 150.0
            assert t.read("Slave2.MotionStatus") & (PC8 | LOCK13) == 0
            assert t.read("Lin.ProfileStatus") == 2
        finally:
            c.close()
