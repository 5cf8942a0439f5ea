"""The seeds' rules, each checked over Modbus TCP against a server of its own (the pytest
plugin ``motion_server.testing``, manual clock), as an integrator comparing with a real
controller would. Each test quotes the seed sentence it is built from.

Site map (seed_rules.toml): M1 = axis 1 and M2 = axis 2 are virtual masters, S = axis 3
a virtual slave (virtual: command and actual agree exactly), Servo = axis 4; 2 ms cycles.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from motion_clients import MotionClient
from motion_server import config
from motion_server.tagmap import build_tagmap, to_dict

SITE = Path(__file__).with_name("seed_rules.toml")
DT = 0.002
M1, M2, S, SERVO = 1, 2, 3, 4

pytestmark = pytest.mark.motion_server(site_map=SITE, opcua=False)


async def execute(mc: MotionClient, instance: str, **operands: Any) -> None:
    """Write the operands, raise Execute for exactly one scan (the one that executes the
    instruction: this call returns after it), then lower it (the same instance needs a
    scan with Execute low before it can fire again)."""
    await mc.write_many({f"{instance}.{k}": v for k, v in operands.items()})
    await mc.write(f"{instance}.Execute", True)
    await mc.step(1)
    await mc.write(f"{instance}.Execute", False)


async def power(mc: MotionClient, *axes: int) -> None:
    for ax in axes:
        await execute(mc, "MSO_1", Axis=ax)
        assert await mc.read("MSO_1.DN") is True
        await mc.step(1)


async def jog(mc: MotionClient, instance: str, axis: int, speed: float) -> None:
    """A time-driven MAJ: ``speed`` mm/s reached in speed / 10000 s."""
    await execute(
        mc, instance, Axis=axis, Speed=speed, AccelRate=10000.0, DecelRate=10000.0, Profile=0
    )
    assert await mc.read(f"{instance}.IP") is True


def master_units(**operands: Any) -> dict[str, Any]:
    """MAJ/MAM operands with every rate in master units (SpeedUnits etc. = 4)."""
    return {
        "SpeedUnits": 4,
        "AccelRate": 1000.0,
        "AccelUnits": 4,
        "DecelRate": 1000.0,
        "DecelUnits": 4,
        "Profile": 0,
        **operands,
    }


# -- MGS ------------------------------------------------------------------------------------
#: logix-MGS, "MGS Changes to Single Axis Status Bits": (bit, name) of every bit in the
#: seed's table, bit numbers of the Logix MotionStatus attribute
MGS_TABLE = {
    2: "Move",
    3: "Jog",
    4: "Gearing",
    5: "Homing",
    6: "Stopping",
    8: "PositionCam",
    9: "TimeCam",
    10: "PositionCamPending",
    11: "TimeCamPending",
    12: "GearingLock",
    13: "PositionCamLock",
    19: "DirectVelocityControl",
    20: "DirectTorqueControl",
}


async def test_mgs_publishes_and_clears_every_status_bit_of_its_table(
    motion_client: MotionClient,
) -> None:
    """logix-MGS: "All: The instruction clears all Motion Status bits", the table naming
    each one (StoppingStatus TRUE while the axes stop)."""
    mc = motion_client
    site = config.load(SITE)
    words = {w["tag"]: w["bits"] for w in to_dict(build_tagmap(site))["packed_words"] if "tag" in w}
    published = {int(n): name for n, name in words["S.MotionStatus"].items()}
    for bit, name in MGS_TABLE.items():
        assert published.get(bit) == name, f"MotionStatus bit {bit} {name} is not published"

    await power(mc, M1, S)
    await jog(mc, "JogM1", M1, 100.0)
    await execute(mc, "MAG_1", SlaveAxis=S, MasterAxis=M1, Ratio=1.0, Clutch=1)
    await execute(mc, "MAM_1", Axis=S, MoveType=1, Position=50.0, Speed=10.0)
    await mc.step(10)
    before = int(await mc.read("S.MotionStatus"))
    assert before & (1 << 2) and before & (1 << 4) and before & (1 << 12)  # Move, Gearing, Lock
    await execute(mc, "MGS_1", Group=1, StopMode=0)
    word = int(await mc.read("S.MotionStatus"))
    assert word & (1 << 6), "StoppingStatus is set while the group stops"
    cleared = [name for bit, name in MGS_TABLE.items() if bit != 6 and word >> bit & 1]
    assert cleared == []


# -- operands a mode does not use -----------------------------------------------------------
async def test_mas_without_change_decel_does_not_judge_decel_rate(
    motion_client: MotionClient,
) -> None:
    """Operands a mode does not use are not judged: MAS with ChangeDecel = No stops at the
    axis Maximum Deceleration, so its DecelRate (0 here, below the map's exclusive
    minimum) is not looked at. At 100 mm/s and 10000 mm/s² the stop takes 0.01 s: 5
    cycles."""
    mc = motion_client
    await power(mc, S)
    await jog(mc, "MAJ_1", S, 100.0)
    await mc.step(10)
    await execute(mc, "MAS_1", Axis=S, StopType=0, ChangeDecel=0, DecelRate=0.0)
    assert (await mc.read("MAS_1.ER"), await mc.read("MAS_1.ERR")) == (False, 0)
    assert await mc.read("MAS_1.DN") is True
    await mc.step(5)
    assert await mc.read("S.CommandVelocity") == 0.0
    assert await mc.read("MAS_1.PC") is True
    # with ChangeDecel = Yes the same DecelRate is used, so judged: ERR 13, EXERR 4
    # (MAS(Axis, MotionControl, StopType, ChangeDecel, DecelRate, ...))
    await jog(mc, "MAJ_1", S, 100.0)
    await mc.step(10)
    await execute(mc, "MAS_1", Axis=S, StopType=0, ChangeDecel=1, DecelRate=0.0)
    assert (await mc.read("MAS_1.ER"), await mc.read("MAS_1.ERR")) == (True, 13)
    assert await mc.read("MAS_1.EXERR") == 4
    assert await mc.read("S.CommandVelocity") == 100.0
    # the map says so: a minimum that is exclusive, and when the operand counts
    tags = {t["name"]: t for t in to_dict(build_tagmap(config.load(SITE)))["tags"]}
    assert tags["MAS_1.DecelRate"]["minimum"] == 0.0
    assert tags["MAS_1.DecelRate"]["exclusive_minimum"] is True
    assert "ChangeDecel = 1 (YES)" in tags["MAS_1.DecelRate"]["description"]
    assert "exclusive_minimum" not in tags["MAS_1.DecelJerk"]  # 0 is a valid jerk


async def test_a_trapezoidal_jog_does_not_judge_its_jerk_operands(
    motion_client: MotionClient,
) -> None:
    """The same rule on MAJ: AccelJerk, DecelJerk and JerkUnits only shape an S-curve;
    with Profile trapezoidal a negative jerk is not looked at."""
    mc = motion_client
    await power(mc, S)
    await execute(
        mc,
        "MAJ_1",
        Axis=S,
        Speed=50.0,
        AccelRate=1000.0,
        DecelRate=1000.0,
        Profile=0,
        AccelJerk=-1.0,
        DecelJerk=-1.0,
    )
    assert (await mc.read("MAJ_1.ER"), await mc.read("MAJ_1.IP")) == (False, True)
    await mc.step(1)
    await execute(
        mc,
        "MAJ_1",
        Axis=S,
        Speed=50.0,
        AccelRate=1000.0,
        DecelRate=1000.0,
        Profile=1,
        AccelJerk=-1.0,
        DecelJerk=100.0,
    )
    assert (await mc.read("MAJ_1.ER"), await mc.read("MAJ_1.ERR")) == (True, 13)


# -- MC_GearInPos ---------------------------------------------------------------------------
async def test_gear_in_pos_immediate_synchronizes_a_slave_beyond_its_sync_position(
    motion_client: MotionClient,
) -> None:
    """plcopen-MC_GearInPos, SyncMode 1: "If either the master or slave axis are beyond
    their respective sync start positions, the slave axis will immediately synchronize
    to the master axis. [...] If the slave axis is ahead of the master axis at the time of
    synchronization, the slave axis will move backwards."

    The master M1 jogs at 100 mm/s far before its start point (MasterSyncPosition 100,
    MasterStartDistance 10); the slave S stands at 0, already 30 mm beyond its
    SlaveSyncPosition -30. Immediate: in sync in the scan the block executes, the slave
    placed on -30 + (master - 100) x 1, about -126: backwards from 0, then following the
    master at its 100 mm/s (ratio 1:1)."""
    mc = motion_client
    await power(mc, M1, S)
    await jog(mc, "JogM1", M1, 100.0)
    await mc.step(4)  # at speed: 100 mm/s from 0.01 s on
    # the block reads the master's actual position, sampled as the cycle begins: the
    # position the previous cycle published
    seen = await mc.read("M1.ActualPosition")
    assert seen < 90.0 - 50.0  # far before its start point
    assert await mc.read("S.CommandPosition") == 0.0
    await execute(
        mc,
        "MC_GearInPos_1",
        Master=M1,
        Slave=S,
        RatioNumerator=1,
        RatioDenominator=1,
        MasterSyncPosition=100.0,
        SlaveSyncPosition=-30.0,
        SyncMode=1,
        MasterStartDistance=10.0,
        BufferMode=0,
    )
    status = await mc.read_many(
        ["MC_GearInPos_1.Error", "MC_GearInPos_1.StartSync", "MC_GearInPos_1.InSync"]
    )
    assert status == {
        "MC_GearInPos_1.Error": False,
        "MC_GearInPos_1.StartSync": True,
        "MC_GearInPos_1.InSync": True,
    }
    s = await mc.read("S.CommandPosition")
    assert s == pytest.approx(-30.0 + (seen - 100.0), abs=1e-9)
    assert s < -100.0, "the slave moved backwards"
    for _ in range(10):
        seen = await mc.read("M1.ActualPosition")
        await mc.step(1)
        assert await mc.read("MC_GearInPos_1.InSync") is True
        s = await mc.read("S.CommandPosition")
        assert s == pytest.approx(-30.0 + (seen - 100.0), abs=1e-9)
        assert await mc.read("S.CommandVelocity") == pytest.approx(100.0, abs=1e-6)


# -- MDAC -----------------------------------------------------------------------------------
#: master-driven ramps so steep (per master mm²) that a change of speed takes one cycle
STEEP = master_units(AccelRate=1e6, DecelRate=1e6)


async def follow_m1(mc: MotionClient) -> None:
    """M1 jogs at 100 mm/s, M2 at 50 mm/s; S follows M1 under MDAC_1 with a master-driven
    jog (1.0 mm per master mm) and a master-driven incremental move (0.5 mm per master
    mm) superimposed: 1.5 · 100 = 150 mm/s."""
    await power(mc, M1, M2, S)
    await jog(mc, "JogM1", M1, 100.0)
    await jog(mc, "JogM2", M2, 50.0)
    await mc.step(10)
    await execute(mc, "MDAC_1", SlaveAxis=S, MasterAxis=M1, MotionType=0, MasterReference=1)
    await execute(mc, "MAJ_1", Axis=S, Direction=0, Speed=1.0, **STEEP)
    await execute(mc, "MAM_1", Axis=S, MoveType=1, Position=1e6, Speed=0.5, **STEEP)
    await mc.step(5)
    assert await mc.read("S.CommandVelocity") == pytest.approx(150.0, abs=1e-6)


async def test_mdac_change_moves_all_master_driven_motion_to_the_new_master(
    motion_client: MotionClient,
) -> None:
    """logix-MDAC: "The axis becomes unlocked from the first Master Axis and reassigned
    to the second Master Axis when this new motion instruction is executed (goes IP)."

    The second MDAC makes the change pending; the new MAJ replaces the jog, and from the
    scan in which it goes IP the move that keeps running follows M2 too: 1.5 · 50 =
    75 mm/s (not 1.0 · 50 + 0.5 · 100). Stopping M1 then leaves the slave alone."""
    mc = motion_client
    await follow_m1(mc)
    await execute(mc, "MDAC_2", SlaveAxis=S, MasterAxis=M2, MotionType=0, MasterReference=1)
    assert await mc.read_many(["MDAC_2.IP", "MDAC_2.AC", "MDAC_1.AC"]) == {
        "MDAC_2.IP": True,
        "MDAC_2.AC": False,
        "MDAC_1.AC": True,
    }
    assert await mc.read("S.CommandVelocity") == pytest.approx(150.0, abs=1e-6)
    await execute(mc, "MAJ_2", Axis=S, Direction=0, Speed=1.0, **STEEP)
    # the scan in which MAJ_2 goes IP
    assert await mc.read_many(["MAJ_2.IP", "MAJ_2.ER", "MDAC_1.IP", "MDAC_2.AC"]) == {
        "MAJ_2.IP": True,
        "MAJ_2.ER": False,
        "MDAC_1.IP": False,
        "MDAC_2.AC": True,
    }
    assert await mc.read("MAM_1.IP") is True
    assert await mc.read("S.CommandVelocity") == pytest.approx(75.0, abs=1e-6)
    await mc.step(20)
    assert await mc.read("S.CommandVelocity") == pytest.approx(75.0, abs=1e-6)
    await execute(mc, "MAS_1", Axis=M1, StopType=0, ChangeDecel=0)
    await mc.step(20)
    assert await mc.read("M1.CommandVelocity") == 0.0
    assert await mc.read("S.CommandVelocity") == pytest.approx(75.0, abs=1e-6)


@pytest.mark.parametrize("history", [10, 37, 111, 250])
async def test_mdac_five_percent_rule_is_judged_from_programmed_values(
    motion_client: MotionClient, history: int
) -> None:
    """logix-MDAC: "If the new final effective Slave Axis speed is less than 5% of its
    original speed after a change in the Master Axis, then the change is not be allowed".

    The slave runs at 1.0 mm per M1 mm, M1 at 100 mm/s: 100 mm/s. After an MDAC to M2
    (40 mm/s) a MAJ at 0.125 mm per master mm would run the slave at 0.125 · 40 = 5 mm/s:
    exactly 5 %, not less, so allowed, however long the axes ran before (``history``
    cycles); 0.12 · 40 = 4.8 mm/s is refused (ERR 103) and changes nothing."""
    mc = motion_client
    await power(mc, M1, M2, S)
    await jog(mc, "JogM1", M1, 100.0)
    await jog(mc, "JogM2", M2, 40.0)
    await execute(mc, "MDAC_1", SlaveAxis=S, MasterAxis=M1, MotionType=0, MasterReference=1)
    await execute(mc, "MAJ_1", Axis=S, Direction=0, Speed=1.0, **STEEP)
    await mc.step(history)
    await execute(mc, "MDAC_2", SlaveAxis=S, MasterAxis=M2, MotionType=0, MasterReference=1)
    await execute(mc, "MAJ_2", Axis=S, Direction=0, Speed=0.12, **STEEP)
    assert (await mc.read("MAJ_2.ER"), await mc.read("MAJ_2.ERR")) == (True, 103)
    assert await mc.read_many(["MAJ_1.IP", "MDAC_1.AC", "MDAC_2.IP"]) == {
        "MAJ_1.IP": True,
        "MDAC_1.AC": True,
        "MDAC_2.IP": True,
    }
    await mc.step(1)
    await execute(mc, "MAJ_2", Axis=S, Direction=0, Speed=0.125, **STEEP)
    assert (await mc.read("MAJ_2.ER"), await mc.read("MAJ_2.IP")) == (False, True)
    assert await mc.read("MDAC_2.AC") is True
    await mc.step(1)
    assert await mc.read("S.CommandVelocity") == pytest.approx(5.0, abs=1e-6)


async def test_a_master_driven_rate_no_planner_can_follow_is_err_13(
    motion_client: MotionClient,
) -> None:
    """A master-driven MAJ at 1.0 mm per master mm with AccelRate 1e-30 mm per master mm²
    would need 1.0 / 1e-30 = 1e30 mm of master travel to reach its speed: refused as an operand
    (ERR 13, EXERR naming AccelRate: Axis 0, Motion Control 1, Direction 2, Speed 3,
    SpeedUnits 4, AccelRate 5), not as an internal error (ERR 1005), and S stays at rest."""
    mc = motion_client
    await power(mc, M1, S)
    await jog(mc, "JogM1", M1, 100.0)
    await execute(mc, "MDAC_1", SlaveAxis=S, MasterAxis=M1, MotionType=0, MasterReference=1)
    await execute(mc, "MAJ_1", Axis=S, Direction=0, Speed=1.0, **master_units(AccelRate=1e-30))
    assert await mc.read_many(["MAJ_1.ER", "MAJ_1.ERR", "MAJ_1.EXERR", "MAJ_1.IP"]) == {
        "MAJ_1.ER": True,
        "MAJ_1.ERR": 13,
        "MAJ_1.EXERR": 5,
        "MAJ_1.IP": False,
    }
    await mc.step(10)
    assert await mc.read("S.CommandVelocity") == 0.0


# -- PLCopen Part 1 -------------------------------------------------------------------------
async def test_mc_power_held_enable_re_enables_the_axis_after_a_reset(
    motion_client: MotionClient,
) -> None:
    """PLCopen Part 1, MC_Power: "As long as 'Enable' is true, power is being enabled";
    "If the MC_Power FB is called with the 'Enable' = true while being in 'Disabled', the
    axis state changes to 'Standstill'". Enable stays TRUE throughout: a drive fault
    takes the servo to ErrorStop (Status FALSE, ErrorID 20); once the cause is gone and
    MC_Reset ran, the axis is back in StandStill (PLCopenState 2) with Status TRUE."""
    mc = motion_client
    await mc.write("MC_Power_1.Axis", SERVO)
    await mc.write("MC_Power_1.Enable", True)
    await mc.step(1)
    assert await mc.read_many(["MC_Power_1.Status", "Servo.PLCopenState"]) == {
        "MC_Power_1.Status": True,
        "Servo.PLCopenState": 2,
    }
    await mc.write("Servo.InjectDriveFault", True)
    await mc.step(1)
    assert await mc.read_many(
        ["MC_Power_1.Status", "MC_Power_1.Error", "MC_Power_1.ErrorID", "Servo.PLCopenState"]
    ) == {
        "MC_Power_1.Status": False,
        "MC_Power_1.Error": True,
        "MC_Power_1.ErrorID": 20,
        "Servo.PLCopenState": 3,
    }
    await mc.write("Servo.InjectDriveFault", False)
    await execute(mc, "MC_Reset_1", Axis=SERVO)
    assert await mc.read("MC_Reset_1.Done") is True
    await mc.step(1)  # MC_Power_1 is scanned before MC_Reset_1: its next scan enables
    assert await mc.read_many(
        ["MC_Power_1.Status", "MC_Power_1.Error", "MC_Power_1.Enable", "Servo.PLCopenState"]
    ) == {
        "MC_Power_1.Status": True,
        "MC_Power_1.Error": False,
        "MC_Power_1.Enable": True,
        "Servo.PLCopenState": 2,
    }


async def test_max_velocity_appl_is_writable_and_judges_the_next_command(
    motion_client: MotionClient,
) -> None:
    """PLCopen Part 1's parameter table: "9 MaxVelocityAppl REAL B R/W". Written to 100
    on S (System maximum 1000 mm/s), it reads back 100 while 8 MaxVelocitySystem stays
    1000, and an MC_MoveVelocity at 150 mm/s on S is refused (ErrorID 13)."""
    mc = motion_client
    await power(mc, S)
    await execute(mc, "MC_WriteParameter_1", Axis=S, ParameterNumber=9, Value=100.0)
    assert await mc.read_many(["MC_WriteParameter_1.Done", "MC_WriteParameter_1.Error"]) == {
        "MC_WriteParameter_1.Done": True,
        "MC_WriteParameter_1.Error": False,
    }
    for number, value in ((9, 100.0), (8, 1000.0)):
        await mc.write_many(
            {"MC_ReadParameter_1.Axis": S, "MC_ReadParameter_1.ParameterNumber": number}
        )
        await mc.write("MC_ReadParameter_1.Enable", True)
        await mc.step(1)
        assert await mc.read("MC_ReadParameter_1.Valid") is True
        assert await mc.read("MC_ReadParameter_1.Value") == value
    await execute(
        mc, "MC_MoveVelocity_1", Axis=S, Velocity=150.0, Acceleration=1000.0, Deceleration=1000.0
    )
    assert await mc.read_many(["MC_MoveVelocity_1.Error", "MC_MoveVelocity_1.ErrorID"]) == {
        "MC_MoveVelocity_1.Error": True,
        "MC_MoveVelocity_1.ErrorID": 13,
    }
    assert await mc.read("S.CommandVelocity") == 0.0
