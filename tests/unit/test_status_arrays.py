"""``Controller.status_arrays()``: the status words of every axis as integer arrays, equal to
the axes' own properties after every cycle and every command, lanes on or off; and kept
current without touching axes whose status cannot have changed."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.kernel import (
    AxisConfig,
    AxisFault,
    AxisType,
    Controller,
    FeedbackSignal,
    GroupConfig,
    MotionError,
    ProgrammedStopMode,
    status_words,
)

from .test_lanes import value


def axes() -> list[AxisConfig]:
    return [
        AxisConfig(1, "V1", AxisType.VIRTUAL, max_acceleration=5000.0, max_deceleration=5000.0),
        AxisConfig(2, "S2", AxisType.SERVO, following_error_limit=1e6,
                   programmed_stop_mode=ProgrammedStopMode.FAST_DISABLE),
        AxisConfig(3, "S3", AxisType.SERVO, rollover=360.0, max_jerk=1e6,
                   programmed_stop_mode=ProgrammedStopMode.HARD_SHUTDOWN),
        AxisConfig(4, "V4", AxisType.VIRTUAL,
                   programmed_stop_mode=ProgrammedStopMode.FAST_SHUTDOWN),
        AxisConfig(5, "W5", AxisType.FEEDBACK_ONLY,
                   feedback_signal=FeedbackSignal.CONSTANT_VELOCITY, signal_velocity=20.0),
    ]  # fmt: skip


def system(lanes: bool) -> MotionSystem:
    cfg = axes()
    return MotionSystem(
        Controller(cfg, [GroupConfig(1, "G", tuple(a.number for a in cfg), 0.002)], lanes=lanes)
    )


def assert_status(ctl: Controller, where: str) -> None:
    st = ctl.status_arrays()
    n = len(ctl.axes)
    for name, arr in st._asdict().items():
        assert arr.shape == (n,) and np.issubdtype(arr.dtype, np.integer), name
    for ax in ctl.axes:
        i = ax.index
        got = (st.axis_state[i], st.plcopen_state[i], st.motion_status[i], st.fault[i])
        want = (int(ax.state), int(ax.plcopen_state), ax.motion_status, int(ax.fault))
        assert got == want, f"{where}: {ax.name}: {got} != {want}"


INSTRUCTIONS = (
    "MSO", "MSF", "MAFR", "MASD", "MASR", "MAJ", "MAJ", "MAM", "MAS", "MCD", "MAG", "MGS",
    "MGSD", "MGSR", "MC_Power", "MC_Reset", "MC_MoveVelocity", "MC_MoveAbsolute", "MC_Halt",
    "MC_Stop", "MC_GearIn", "MC_GearOut",
)  # fmt: skip


@st.composite
def instruction(draw: st.DrawFn) -> tuple[str, object, int]:
    type_name = draw(st.sampled_from(INSTRUCTIONS))
    cls = instruction_type(type_name)
    ops = {op.name: draw(value(op)) for op in cls.OPERANDS}
    for key in ("Axis", "SlaveAxis", "MasterAxis", "Master", "Slave"):
        if key in ops:
            ops[key] = draw(st.integers(1, 5))
    if "Group" in ops:
        ops["Group"] = 1
    return "instruction", (type_name, ops), draw(st.integers(1, 40))


@st.composite
def direct(draw: st.DrawFn) -> tuple[str, object, int]:
    """A command straight to the kernel, or an attribute a host sets (retain, MC_Stop)."""
    what = draw(
        st.sampled_from(
            ["servo_on", "servo_off", "fault", "fault_reset", "shutdown", "shutdown_reset",
             "group_stop", "homed", "latch", "unlatch"]
        )
    )  # fmt: skip
    arg = (draw(st.integers(1, 5)), draw(st.sampled_from([None, *ProgrammedStopMode])))
    return "direct", (what, arg), draw(st.integers(0, 30))


def apply_direct(ctl: Controller, what: str, arg: tuple[int, object]) -> None:
    ax = ctl.axis(arg[0])
    try:
        if what == "fault":
            ctl.fault(ax, AxisFault.POSITION_ERROR)
        elif what == "group_stop":
            ctl.group_stop(1, arg[1])  # type: ignore[arg-type]
        elif what == "homed":
            ax.homed = not ax.homed
        elif what == "latch":
            ax.stop_latch = "host"
        elif what == "unlatch":
            ax.stop_latch = None
        else:
            getattr(ctl, what)(ax)
    except MotionError:
        pass  # refused: the status must still be right


@settings(max_examples=60, deadline=None)
@given(script=st.lists(st.one_of(instruction(), direct()), min_size=1, max_size=12))
def test_status_arrays_equal_the_axis_properties_after_every_cycle_and_command(
    script: list[tuple[str, object, int]],
) -> None:
    for lanes, as_arrays in ((True, status_words.AS_ARRAYS), (False, 1), (True, 1)):
        # (as_arrays 1: the words of axes without processes derived as arrays, however few)
        try:
            saved, status_words.AS_ARRAYS = status_words.AS_ARRAYS, as_arrays
            run_script(system(lanes), script)
        finally:
            status_words.AS_ARRAYS = saved


def run_script(s: MotionSystem, script: list[tuple[str, object, int]]) -> None:
    """The script's commands and cycles on ``s``, the status checked after each."""
    ctl = s.ctl
    assert_status(ctl, "start")
    for n in (1, 2, 3, 4):
        ctl.servo_on(ctl.axis(n))
    assert_status(ctl, "servo on")
    for k, (kind, payload, cycles) in enumerate(script):
        if kind == "instruction":
            type_name, ops = payload  # type: ignore[misc]
            inst = s.add(type_name, f"I{k}")
            inst.inputs.update(ops)
            inst.inputs[inst.TRIGGER] = True
            s.cycle()
            assert_status(ctl, f"{k} {type_name} {ops}")
            inst.inputs[inst.TRIGGER] = False
        else:
            what, arg = payload  # type: ignore[misc]
            apply_direct(ctl, what, arg)
            assert_status(ctl, f"{k} {what} {arg}")
        for c in range(cycles):
            s.cycle()
            assert_status(ctl, f"{k} cycle {c}")


def test_steady_lanes_leave_nothing_to_derive_in_python() -> None:
    """334 axes jogging steadily in the lanes: after one call, stepping marks no axis for
    re-derivation, so a call costs only its array operations."""
    cfg = [AxisConfig(k, f"A{k}", AxisType.SERVO) for k in range(1, 335)]
    ctl = Controller(cfg, [GroupConfig(1, "G", tuple(a.number for a in cfg), 0.002)])
    from motion_server.kernel import JogProcess, Limits

    for ax in ctl.axes:
        ctl.servo_on(ax)
        ctl.start(ax, lambda v, a: JogProcess(0.002, 123.4567, Limits(200.0, 1e4, 1e4), v, a))
    ctl.run(20)
    assert sum(len(lanes) for lanes in ctl.motion.lanes.values()) == 334
    assert_status(ctl, "at speed")
    for _ in range(10):
        ctl.step()
        assert ctl.arrays.dirty == set()
        assert_status(ctl, "steady")
