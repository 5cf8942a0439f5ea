"""MC_HaltSuperimposed (PLCopen Part 1): "commands a halt to all superimposed motions of
the axis. The underlying motion is not interrupted."

Kinematics (trapezoid, 2 ms cycles), on the rig of test_plcopen_superimposed: a jog at
40 u/s; a superimposed move of 10 u at VelocityDiff 20 u/s, 200 u/s²: after 0.2 s it has
ramped up for 0.1 s (1 u) and cruised for 0.1 s (2 u): 3 u at 20 u/s. Halted at 100
u/s², its 20 u/s ramp to rest in 0.2 s = 100 cycles, covering 20² / (2 · 100) = 2 u: the
axis ends 5 u ahead of the jog alone, back at the jog's 40 u/s, still jogging.
"""

from __future__ import annotations

from typing import Any

import pytest

from motion_server.instructions import MotionSystem
from motion_server.kernel import ErrorCode, PLCopenState

from .test_plcopen_single_axis import execute
from .test_plcopen_superimposed import DT, block, jog, plant, superimposed


def halt(system: MotionSystem, **ops: Any) -> Any:
    return block(system, "MC_HaltSuperimposed", "HaltSup", **{"Deceleration": 100.0, **ops})


def test_a_halt_ends_the_superimposed_move_only_and_the_jog_goes_on() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog(system)
    start = ax.command_position
    sup = superimposed(system)
    execute(system, sup, True, 100)  # 0.2 s
    cycles = 100
    assert ax.command_velocity == pytest.approx(60.0)
    assert ax.command_position - start - 40.0 * DT * cycles == pytest.approx(3.0)
    hs = halt(system)
    execute(system, hs, True)
    cycles += 1
    assert hs.outputs["Busy"] and hs.outputs["Active"] and not hs.outputs["Done"]
    assert sup.outputs["CommandAborted"] and not sup.outputs["Busy"]
    assert ax.command_velocity == pytest.approx(60.0 - 100.0 * DT)
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    execute(system, hs, True, 98)
    cycles += 98
    assert not hs.outputs["Done"] and ax.command_velocity == pytest.approx(40.2)
    execute(system, hs, True)
    cycles += 1
    assert hs.outputs["Done"] and not hs.outputs["Busy"] and not hs.outputs["Error"]
    assert ax.command_velocity == pytest.approx(40.0)
    assert ax.command_position - start - 40.0 * DT * cycles == pytest.approx(5.0)
    # the underlying jog was never interrupted
    assert mv.outputs["Busy"] and mv.outputs["InVelocity"] and not mv.outputs["CommandAborted"]
    assert ax.plcopen_state == PLCopenState.CONTINUOUS_MOTION
    execute(system, hs, False, 10)
    assert ax.command_velocity == pytest.approx(40.0)


def test_a_halt_of_a_superimposed_move_on_an_axis_at_rest_brings_it_to_standstill() -> None:
    """At rest a superimposed move is a relative move: halted after 0.2 s at 3 u and
    20 u/s, the axis stops 2 u further on, at 5 u, and is in StandStill."""
    system = plant()
    ax = system.ctl.axis(2)
    sup = superimposed(system)
    execute(system, sup, True, 100)
    assert ax.plcopen_state == PLCopenState.DISCRETE_MOTION
    hs = halt(system)
    execute(system, hs, True, 100)
    assert hs.outputs["Done"]
    assert ax.command_velocity == 0.0
    assert ax.command_position == pytest.approx(5.0)
    assert ax.plcopen_state == PLCopenState.STANDSTILL


def test_nothing_superimposed_is_done_at_once_and_changes_nothing() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    mv = jog(system)
    hs = halt(system)
    execute(system, hs, True)
    assert hs.outputs["Done"] and not hs.outputs["Error"]
    assert ax.command_velocity == pytest.approx(40.0) and mv.outputs["Busy"]


def test_a_deceleration_beyond_the_maximum_brakes_at_the_maximum() -> None:
    """The axis maximum deceleration is 5000 u/s²: a halt asked at 1e6 ramps the 20 u/s
    superimposed velocity down at 5000, in 20 / 5000 = 4 ms = 2 cycles."""
    system = plant()
    ax = system.ctl.axis(2)
    jog(system)
    sup = superimposed(system)
    execute(system, sup, True, 100)
    hs = halt(system, Deceleration=1e6)
    execute(system, hs, True)
    assert ax.command_velocity == pytest.approx(60.0 - 5000.0 * DT)
    execute(system, hs, True)
    assert hs.outputs["Done"] and ax.command_velocity == pytest.approx(40.0)


@pytest.mark.parametrize("decel", [0.0, -1.0, float("nan")])
def test_a_bad_deceleration_is_error_13_and_the_superimposed_move_goes_on(decel: float) -> None:
    system = plant()
    ax = system.ctl.axis(2)
    jog(system)
    sup = superimposed(system)
    execute(system, sup, True, 100)
    hs = halt(system, Deceleration=decel)
    execute(system, hs, True)
    assert hs.outputs["Error"] and hs.outputs["ErrorID"] == ErrorCode.PARAMETER_OUT_OF_RANGE
    assert sup.outputs["Busy"] and ax.command_velocity == pytest.approx(60.0)


def test_a_new_superimposed_move_takes_over_from_the_halt() -> None:
    system = plant()
    ax = system.ctl.axis(2)
    jog(system)
    sup = superimposed(system)
    execute(system, sup, True, 100)
    hs = halt(system)
    execute(system, hs, True, 10)  # 20 - 10 x 0.2 = 18 u/s superimposed
    assert ax.command_velocity == pytest.approx(58.0)
    sup2 = superimposed(system, "Super2")
    execute(system, sup2, True)
    assert hs.outputs["CommandAborted"] and sup2.outputs["Busy"]
    # it inherits the 18 u/s and accelerates back toward its 20 u/s at 200 u/s²
    assert ax.command_velocity == pytest.approx(58.0 + 200.0 * DT)
