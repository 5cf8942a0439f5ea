"""Commands beyond the axis's limits, per dialect (docs/semantics.md).

One virtual axis, Maximum Speed V = 1000 mm/s, maximum acceleration and deceleration
D = 10 000 mm/s², coarse update dt = 2 ms. First principles: from V a stop at D takes
V / D = 0.1 s = 50 cycles; before, a MAJ at 1e6 mm/s (AccelRate 1e6) reached 102 000 mm/s
in 50 cycles and its group stop took 10.2 s.

- Logix: a time-driven speed beyond the Maximum Speed (units/s or % of it) is limited to
  it; the instruction is accepted and the axis runs at V.
- PLCopen: a Velocity, Acceleration, Deceleration or Jerk beyond the axis maxima is
  refused (Error, ErrorID 13), and nothing moves.
Either way a group stop (MGS) then completes within V / D.
"""

from __future__ import annotations

import numpy as np
import pytest

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import AxisConfig, AxisType, ErrorCode

from ..support import make_system, trigger

DT = 0.002
V = 1000.0
D = 10_000.0
STOP_CYCLES = round(V / D / DT)  # 50
REAL_MAX = 3.4028234663852886e38  # the largest REAL (float32)


def powered(max_jerk: float = 0.0) -> MotionSystem:
    system = make_system(
        AxisConfig(
            1,
            "Axis1",
            AxisType.VIRTUAL,
            max_velocity=V,
            max_acceleration=D,
            max_deceleration=D,
            max_jerk=max_jerk,
        ),
        period=DT,
    )
    trigger(system, system.add("MSO", "MSO_1", {"Axis": 1}))
    return system


def velocities(system: MotionSystem, cycles: int) -> np.ndarray:
    ax = system.ctl.axis(1)
    out = np.empty(cycles)
    for k in range(cycles):
        system.cycle()
        out[k] = ax.command_velocity
    return out


def group_stop_cycles(system: MotionSystem) -> int:
    """Cycles an MGS needs to bring the axis to rest (the MGS scan included)."""
    ax = system.ctl.axis(1)
    mgs = system.add("MGS", "MGS_1", {"Group": 1})
    trigger(system, mgs)
    n = 1
    while ax.command_velocity != 0.0 and n < 100_000:
        system.cycle()
        n += 1
    return n


def bit(inst: Instruction, name: str) -> bool:
    return bool(inst.outputs[name])


# -- Logix: limited to the Maximum Speed ----------------------------------------------------
@pytest.mark.parametrize(
    ("speed", "units"),
    [(1e6, 0), (REAL_MAX, 0), (150.0, 1), (V, 0)],
    ids=["1e6 units/s", "REAL max", "150 % of maximum", "exactly the maximum"],
)
def test_logix_jog_beyond_maximum_speed_runs_at_it(speed: float, units: int) -> None:
    system = powered()
    maj = system.add(
        "MAJ",
        "MAJ_1",
        {"Axis": 1, "Speed": speed, "SpeedUnits": units, "AccelRate": 1e6, "DecelRate": D},
    )
    trigger(system, maj)
    assert bit(maj, "IP") and not bit(maj, "ER")
    v = velocities(system, 60)
    assert v.max() == V  # reached (1e6 mm/s² reaches it within one cycle) and never beyond
    assert group_stop_cycles(system) <= STOP_CYCLES + 1


def test_logix_move_at_the_largest_real_speed_stops_in_time() -> None:
    """A MAM at 3.4e38 mm/s used to make a stop that never completed."""
    system = powered()
    mam = system.add(
        "MAM",
        "MAM_1",
        {"Axis": 1, "MoveType": 1, "Position": 1e6, "Speed": REAL_MAX,
         "AccelRate": REAL_MAX, "DecelRate": REAL_MAX},
    )  # fmt: skip
    trigger(system, mam)
    assert bit(mam, "IP") and not bit(mam, "ER")
    v = velocities(system, 20)
    assert v.max() == V
    n = group_stop_cycles(system)
    assert n <= STOP_CYCLES + 1
    assert system.ctl.axis(1).command_velocity == 0.0


def test_logix_mcd_beyond_maximum_speed_is_limited() -> None:
    system = powered()
    maj = system.add("MAJ", "MAJ_1", {"Axis": 1, "Speed": 100.0, "AccelRate": D, "DecelRate": D})
    trigger(system, maj)
    velocities(system, 10)
    mcd = system.add("MCD", "MCD_1", {"Axis": 1, "MotionType": 0, "ChangeSpeed": 1, "Speed": 1e6})
    trigger(system, mcd)
    assert not bit(mcd, "ER")
    # 100 -> 1000 mm/s at 10 000 mm/s²: 0.09 s = 45 cycles, then at the maximum
    v = velocities(system, 100)
    assert v.max() == V and v[-1] == V


# -- PLCopen: refused --------------------------------------------------------------------
@pytest.mark.parametrize(
    ("operand", "value"),
    [
        ("Velocity", 1e6),
        ("Velocity", V * (1.0 + 1e-12)),
        ("Velocity", REAL_MAX),
        ("Acceleration", 2.0 * D),
        ("Deceleration", 2.0 * D),
        ("Jerk", 2e6),
    ],
)
def test_plcopen_move_beyond_the_axis_maxima_is_refused(operand: str, value: float) -> None:
    system = powered(max_jerk=1e6)
    ok = {"Velocity": 100.0, "Acceleration": D, "Deceleration": D, "Jerk": 0.0}
    jog = system.add("MC_MoveVelocity", "MC_MoveVelocity_1", {"Axis": 1, **ok})
    trigger(system, jog)
    velocities(system, 20)
    assert system.ctl.axis(1).command_velocity == 100.0
    for block, extra in (
        ("MC_MoveVelocity", {}),
        ("MC_MoveAbsolute", {"Position": 500.0}),
        ("MC_MoveRelative", {"Distance": 500.0}),
    ):
        b = system.add(block, f"{block}_2", {"Axis": 1, **ok, **extra, operand: value})
        trigger(system, b)
        assert bit(b, "Error") and b.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
        assert not bit(b, "Busy")
    # the running jog goes on undisturbed
    assert bit(jog, "Busy") and not bit(jog, "CommandAborted")
    assert np.all(velocities(system, 5) == 100.0)


def test_plcopen_move_at_the_maxima_runs_and_a_group_stop_takes_v_over_d() -> None:
    system = powered()
    b = system.add(
        "MC_MoveVelocity",
        "MC_MoveVelocity_1",
        {"Axis": 1, "Velocity": V, "Acceleration": D, "Deceleration": D},
    )
    trigger(system, b)
    assert not bit(b, "Error")
    v = velocities(system, 60)
    assert v.max() == V and v[-1] == V
    assert group_stop_cycles(system) == STOP_CYCLES


# -- a group stop from beyond the Maximum Speed -------------------------------------------
def two_axes(jog: bool = True) -> MotionSystem:
    """Axis 1 (master) and axis 2, both as in :func:`powered`, in one group; the master
    jogs to V (``jog``) from the scan that returns."""
    cfg = {"max_velocity": V, "max_acceleration": D, "max_deceleration": D}
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, **cfg),  # type: ignore[arg-type]
        AxisConfig(2, "Axis2", AxisType.VIRTUAL, **cfg),  # type: ignore[arg-type]
        period=DT,
    )
    for n in (1, 2):
        trigger(system, system.add("MSO", f"MSO_{n}", {"Axis": n}))
    maj = system.add("MAJ", "JOG_1", {"Axis": 1, "Speed": V, "AccelRate": D, "DecelRate": D})
    if jog:
        trigger(system, maj)
    return system


def stop_all(system: MotionSystem) -> int:
    """Cycles an MGS needs to bring both axes to rest (the MGS scan included)."""
    a1, a2 = system.ctl.axis(1), system.ctl.axis(2)
    trigger(system, system.add("MGS", "MGS_1", {"Group": 1}))
    n = 1
    while (a1.command_velocity, a2.command_velocity) != (0.0, 0.0) and n < 100_000:
        system.cycle()
        n += 1
    return n


def test_a_geared_slave_beyond_maximum_speed_stops_within_v_over_d() -> None:
    """Logix MAG Ratio 5 (|Ratio| up to 9.99999) on a master at 1000 mm/s: the slave runs
    at 5000 mm/s (gearing is not limited). A group stop at the maximum deceleration would
    need 0.5 s; it ends within V / D as a stop from the Maximum Speed."""
    system = two_axes()
    mag = system.add("MAG", "MAG_1", {"SlaveAxis": 2, "MasterAxis": 1, "Ratio": 5.0, "Clutch": 1})
    trigger(system, mag)
    assert bit(mag, "IP") and not bit(mag, "ER")
    system.cycle(60)
    assert system.ctl.axis(2).command_velocity == pytest.approx(5.0 * V, rel=1e-12)
    assert stop_all(system) <= STOP_CYCLES + 1


def test_superimposed_motion_beyond_maximum_speed_stops_within_v_over_d() -> None:
    """A MAJ and an incremental MAM, each at the Maximum Speed, superimpose to 2000 mm/s
    on axis 2: the group stop still ends within V / D (not 2 V / D)."""
    system = two_axes()
    dyn = {"AccelRate": D, "DecelRate": D}
    trigger(system, system.add("MAJ", "MAJ_2", {"Axis": 2, "Speed": V, **dyn}))
    trigger(
        system,
        system.add("MAM", "MAM_2", {"Axis": 2, "MoveType": 1, "Position": 1e5, "Speed": V, **dyn}),
    )
    system.cycle(60)
    assert system.ctl.axis(2).command_velocity == 2.0 * V
    assert stop_all(system) <= STOP_CYCLES + 1


def test_plcopen_gear_in_beyond_maximum_speed_stops_within_v_over_d() -> None:
    """MC_GearIn 500:1 engaged on a master at rest (in gear at once: nothing to catch up,
    and its catch-up dynamics within the slave's maxima, as docs/semantics.md requires),
    then the master jogs to V: the slave runs at 5e5 mm/s, and a group stop still ends
    within V / D."""
    system = two_axes(jog=False)
    gear = system.add(
        "MC_GearIn",
        "MC_GearIn_1",
        {"Master": 1, "Slave": 2, "RatioNumerator": 500, "RatioDenominator": 1,
         "Acceleration": D, "Deceleration": D},
    )  # fmt: skip
    trigger(system, gear)
    assert not bit(gear, "Error")
    trigger(system, system["JOG_1"])
    system.cycle(60)
    assert bit(gear, "InGear")
    assert system.ctl.axis(2).command_velocity == pytest.approx(5e5, rel=1e-12)
    assert stop_all(system) <= STOP_CYCLES + 1
