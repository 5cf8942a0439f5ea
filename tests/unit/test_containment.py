"""Nothing that goes wrong inside a step ends ``Controller.step()``: a process that raises
something other than MotionError ends in ERROR with ERR 1005 and its axis ramps to rest;
a value that is not finite faults its axis (AxisFault.NUMERIC) and stays out of the
arrays; both are recorded for the host to log, once."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisState,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    JogProcess,
    Limits,
    Process,
    ProcessKind,
    ProcessState,
)
from motion_server.kernel.gearing import GearProcess, GearTerm, MasterSource
from motion_server.kernel.state import StepContext

from ..support import make_system, trigger

DT = 0.002
DECEL = 5000.0


class Breaks(Process):
    """Runs at a constant velocity, then raises ``exc`` (a bug, a library failing)."""

    kind = ProcessKind.MOVE

    def __init__(self, velocity: float, cycles: int, exc: BaseException) -> None:
        super().__init__()
        self.velocity = velocity
        self.left = cycles
        self.exc = exc

    def step(self, ctx: StepContext, dt: float) -> None:
        self.left -= 1
        if self.left < 0:
            self.position = math.nan  # half-done work the kernel must not keep
            raise self.exc
        self.position += self.velocity * dt


class Runaway(Process):
    """Commands a position that is (or becomes) beyond any float."""

    kind = ProcessKind.MOVE

    def __init__(self, position: float) -> None:
        super().__init__()
        self.target = position

    def step(self, ctx: StepContext, dt: float) -> None:
        self.position = self.target


def controller() -> Controller:
    axes = [
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, max_deceleration=DECEL),
        AxisConfig(2, "Axis2", AxisType.SERVO, max_deceleration=DECEL),
        AxisConfig(3, "Wheel", AxisType.FEEDBACK_ONLY, conversion_constant=1000.0),
        AxisConfig(4, "Axis4", AxisType.SERVO),
    ]
    ctl = Controller(axes, [GroupConfig(1, "G", (1, 2, 3, 4), DT)])
    for n in (1, 2, 4):
        ctl.servo_on(ctl.axis(n))
    return ctl


@pytest.mark.parametrize("exc", [RuntimeError("bug"), OverflowError("x"), ZeroDivisionError()])
def test_a_process_that_raises_ends_with_err_1005_and_the_axis_ramps_down(
    exc: BaseException,
) -> None:
    ctl = controller()
    ax = ctl.axis(1)
    p = ctl.start(ax, lambda v, a: Breaks(100.0, 10, exc), replace=None)
    vel = []
    for _ in range(30):
        ctl.step()
        vel.append(ax.command_velocity)
    assert p.state == ProcessState.ERROR and p.error_code == ErrorCode.INTERNAL_ERROR == 1005
    # 10 cycles at 100, then 100 / (5000 x 0.002) = 10 cycles down at 10 per cycle
    expected = [100.0] * 10 + list(np.maximum(100.0 - 10.0 * np.arange(1, 21), 0.0))
    np.testing.assert_allclose(vel, expected, atol=1e-9)
    assert math.isfinite(ax.command_position) and ax.command_position == pytest.approx(
        100.0 * 10 * DT + 0.5 * 100.0 * 10 * DT
    )
    errors = ctl.take_internal_errors()
    assert len(errors) == 1
    name, what, caught = errors[0]
    assert (name, what, caught) == ("Axis1", repr(p), exc)
    assert ctl.take_internal_errors() == []


def test_the_instruction_that_started_it_reports_err_1005() -> None:
    system = make_system(
        AxisConfig(1, "Axis1", AxisType.VIRTUAL, max_acceleration=1e4, max_deceleration=1e4)
    )
    trigger(system, system.add("MSO", "MSO_1", {"Axis": 1}))
    maj = system.add("MAJ", "MAJ_1", {"Axis": 1, "Speed": 10.0, "AccelRate": 1e4,
                                      "DecelRate": 1e4})  # fmt: skip
    trigger(system, maj)
    system.cycle(5)
    process = system.ctl.axis(1).active()[0]
    system.ctl.settle(system.ctl.axis(1))

    def broken(ctx: StepContext, dt: float) -> None:
        raise KeyError("unexpected")

    process.step = broken  # type: ignore[method-assign]
    system.cycle(3)
    assert maj.outputs["ER"] and maj.outputs["ERR"] == ErrorCode.INTERNAL_ERROR
    assert len(system.ctl.take_internal_errors()) == 1


def test_a_feedback_reading_that_overflows_faults_the_axis_instead_of_raising() -> None:
    """8.98e307 x 1000 counts/unit is beyond the largest float: ``round`` would raise."""
    ctl = controller()
    wheel = ctl.axis(3)
    ctl.set_feedback_input(wheel, 12.5)
    ctl.step()
    assert wheel.actual_position == 12.5
    ctl.set_feedback_input(wheel, 8.98e307)
    jog = ctl.start(ctl.axis(4), lambda v, a: JogProcess(DT, 10.0, Limits(10.0, 1e4, 1e4), v, a))
    ctl.step()  # does not raise
    assert wheel.state == AxisState.AXIS_FAULTED and wheel.fault & AxisFault.NUMERIC
    assert wheel.actual_position == 12.5 and wheel.actual_velocity == 0.0
    assert [(e[0], e[1]) for e in ctl.take_internal_errors()] == [("Wheel", "feedback")]
    ctl.step()
    assert jog.active and ctl.axis(4).command_velocity > 0.0  # the others go on


@pytest.mark.parametrize(("position", "where"), [(math.inf, "command"), (1.7e308, "drive model")])
def test_a_command_that_is_not_finite_or_overflows_the_drive_faults_its_axis(
    position: float, where: str
) -> None:
    """An infinite command is refused before the drive sees it; a finite one the drive
    model cannot follow (its slope overflows) is caught after it; either way the axis is
    faulted (drive off), its values stay finite, and the step goes on."""
    ctl = controller()
    ax = ctl.axis(2)
    ctl.start(ax, lambda v, a: JogProcess(DT, 10.0, Limits(10.0, 1e4, 1e4), v, a))
    ctl.run(10)
    ctl.start(ax, lambda v, a: Runaway(position), replace=None)
    ctl.step()
    assert ax.state == AxisState.AXIS_FAULTED and ax.fault == AxisFault.NUMERIC
    for name in ("cmd_pos", "cmd_vel", "cmd_acc", "act_x", "act_pos", "act_vel", "drv_cmd"):
        assert np.isfinite(getattr(ctl.arrays, name)).all(), name
    assert [(e[0], e[1]) for e in ctl.take_internal_errors()] == [("Axis2", where)]
    ctl.run(5)  # coasting from there stays finite, and is not faulted again
    assert np.isfinite(ctl.arrays.kinematics).all()
    assert ctl.take_internal_errors() == []


@pytest.mark.parametrize("lanes", [True, False])
def test_a_gear_that_overflows_faults_the_slave_with_or_without_lanes(lanes: bool) -> None:
    """A real-ratio gear of 1e6 on a master at 1e303 computes an infinite command for the
    slave, laned or not: the slave is faulted, the master goes on."""
    axes = [
        AxisConfig(1, "M", AxisType.VIRTUAL),
        AxisConfig(2, "S", AxisType.VIRTUAL),
    ]
    ctl = Controller(axes, [GroupConfig(1, "G", (1, 2), DT)], lanes=lanes)
    master, slave = ctl.axis(1), ctl.axis(2)
    for ax in (master, slave):
        ctl.servo_on(ax)
    ctl.start(
        slave,
        lambda v, a: GearProcess(ctl, slave, (GearTerm(1, MasterSource.COMMAND, 1e6),)),
    )
    ctl.run(3)
    ctl.start(master, lambda v, a: Runaway(1e303))
    ctl.run(2)
    assert slave.state == AxisState.AXIS_FAULTED and slave.fault == AxisFault.NUMERIC
    assert master.state == AxisState.SERVO_CONTROL and master.command_position == 1e303
    assert np.isfinite(ctl.arrays.kinematics).all()


@pytest.mark.parametrize("batched", [False, True])
def test_overflowing_values_warn_neither_in_a_step_nor_in_a_batch(batched: bool) -> None:
    """Non-finite values are screened, not warned about: a step on its own sets numpy's
    error state itself, steps in ``Controller.batch()`` share the batch's; numpy's own
    setting is back after the batch. The vectorised paths (lanes, a group of 8 axes)
    overflow here: a gear of 1e6 on masters at 1e303."""
    n = 4
    axes = [AxisConfig(k, f"M{k}", AxisType.VIRTUAL) for k in range(1, n + 1)]
    axes += [AxisConfig(n + k, f"S{k}", AxisType.SERVO) for k in range(1, n + 1)]
    ctl = Controller(axes, [GroupConfig(1, "G", tuple(range(1, 2 * n + 1)), DT)], lanes=True)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    for k in range(1, n + 1):
        slave = ctl.axis(n + k)
        ctl.start(
            slave,
            lambda v, a, k=k, slave=slave: GearProcess(
                ctl, slave, (GearTerm(k, MasterSource.COMMAND, 1e6),)
            ),
        )
    ctl.run(3)
    for k in range(1, n + 1):
        ctl.start(ctl.axis(k), lambda v, a: Runaway(1e303))
    before = np.geterr()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if batched:
            with ctl.batch():
                ctl.step()
                ctl.step()
        else:
            ctl.step()
            ctl.step()
    assert np.geterr() == before
    for k in range(1, n + 1):
        slave = ctl.axis(n + k)
        assert slave.state == AxisState.AXIS_FAULTED and slave.fault == AxisFault.NUMERIC
    assert np.isfinite(ctl.arrays.kinematics).all()
