"""The fast lanes change nothing but speed: a controller with lanes and one without, fed
the same commands, agree bit for bit on every array and every instruction output after
every cycle (the lanes repeat the processes' floating-point operations in order)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.instructions.schema import Kind, Operand, TagType
from motion_server.kernel import (
    AxisConfig,
    AxisState,
    AxisType,
    Controller,
    GroupConfig,
    GroupState,
    MotionGroup,
)

ARRAYS = ("cmd_pos", "cmd_vel", "cmd_acc", "act_x", "act_pos", "act_vel", "drive_on")


def axes() -> list[AxisConfig]:
    return [
        AxisConfig(1, "V1", AxisType.VIRTUAL, max_acceleration=5000.0, max_deceleration=5000.0),
        AxisConfig(2, "V2", AxisType.VIRTUAL, max_acceleration=5000.0, max_deceleration=5000.0),
        AxisConfig(3, "S3", AxisType.SERVO, following_error_limit=1e6),
        AxisConfig(4, "S4", AxisType.SERVO, following_error_limit=1e6, rollover=360.0),
        AxisConfig(5, "S5", AxisType.SERVO, following_error_limit=1e6, conversion_constant=1000),
        AxisConfig(6, "W6", AxisType.FEEDBACK_ONLY, conversion_constant=100.0),
    ]


def pair() -> tuple[MotionSystem, MotionSystem]:
    """Two identical systems: fast lanes on and off."""
    out = []
    for lanes in (True, False):
        cfg = axes()
        group = GroupConfig(1, "G", tuple(a.number for a in cfg), 0.002)
        s = MotionSystem(Controller(cfg, [group], lanes=lanes))
        for n in (1, 2, 3, 4, 5):
            s.ctl.servo_on(s.ctl.axis(n))
        out.append(s)
    return out[0], out[1]


def group_state_from_axes(g: MotionGroup) -> GroupState:
    """A group's state from its definition, read axis by axis (``MotionGroup.state``
    reads the status arrays instead)."""
    if any(a.state == AxisState.AXIS_FAULTED for a in g.axes):
        return GroupState.FAULTED
    motion_axes = [a for a in g.axes if a.type != AxisType.FEEDBACK_ONLY]
    if motion_axes and all(a.state == AxisState.AXIS_SHUTDOWN for a in motion_axes):
        return GroupState.SHUTDOWN
    if any(not s.complete for s in g.stops) or any(a.stopping for a in g.axes):
        return GroupState.STOPPING
    return GroupState.NORMAL


def assert_same(fast: MotionSystem, ref: MotionSystem, where: str) -> None:
    # the group state from the status arrays, before and after they are brought up to
    # date (the scan does that after every cycle)
    for s in (fast, ref):
        for g in s.ctl.groups:
            assert g.state == group_state_from_axes(g), f"{where}: {g.name}"
        s.ctl.status_arrays()
        for g in s.ctl.groups:
            assert g.state == group_state_from_axes(g), f"{where}: {g.name}, up to date"
    for name in ARRAYS:
        a, b = getattr(fast.ctl, name), getattr(ref.ctl, name)
        assert np.array_equal(a, b), f"{where}: {name} {a} != {b}"
    for ax_f, ax_r in zip(fast.ctl.axes, ref.ctl.axes, strict=True):
        assert (ax_f.state, ax_f.motion_status, ax_f.base) == (
            ax_r.state,
            ax_r.motion_status,
            ax_r.base,
        ), f"{where}: {ax_f.name}"
    for name, inst in ref.instances.items():
        assert fast.instances[name].outputs == inst.outputs, f"{where}: {name}"


def laned(s: MotionSystem) -> int:
    return sum(1 for ax in s.ctl.axes for p in ax.processes if p.lane is not None)


TYPES = (
    "MAJ",
    "MAJ",
    "MAG",
    "MAG",
    "MAM",
    "MAS",
    "MCD",
    "MSO",
    "MSF",
    "MGS",
    "MGSD",
    "MGSR",
    "MC_GearIn",
    "MC_GearOut",
    "MC_CombineAxes",
    "MC_MoveVelocity",
    "MC_Halt",
    "MC_Stop",
)


def value(op: Operand) -> st.SearchStrategy[object]:
    """Mostly sensible operands (so that jogs reach speed and gears lock), some not."""
    if op.kind == Kind.AXIS:
        return st.integers(1, 6)
    if op.type == TagType.BOOL:
        return st.booleans()
    if op.type.is_float:
        return st.one_of(
            st.sampled_from([0.5, 1.0, 2.0, 3.0, -1.0, 10.0, 100.0, 1000.0, 1e4]),
            st.floats(-300.0, 300.0, allow_nan=False),
        )
    return st.integers(0, 3)


@st.composite
def command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    type_name = draw(st.sampled_from(TYPES))
    cls = instruction_type(type_name)
    ops = {op.name: draw(value(op)) for op in cls.OPERANDS}
    if "Group" in ops:
        ops["Group"] = 1
    return type_name, ops, draw(st.integers(1, 60))


def run_pair(
    fast: MotionSystem,
    ref: MotionSystem,
    script: list[tuple[str, dict[str, object], int]],
    prefix: str = "I",
) -> int:
    """Apply ``script`` to both systems, comparing after every cycle; the largest number
    of processes seen in a lane at once."""
    most = 0
    for i, (type_name, ops, cycles) in enumerate(script):
        for s in (fast, ref):
            inst = s.instances.get(f"{prefix}{i}") or s.add(type_name, f"{prefix}{i}", {})
            inst.inputs.update(ops)
            inst.inputs[inst.TRIGGER] = True
            s.ctl.set_feedback_input(s.ctl.axis(6), 0.37 * i * i)
        for k in range(cycles + 1):
            if k == cycles:
                for s in (fast, ref):
                    s.instances[f"{prefix}{i}"].inputs[s.instances[f"{prefix}{i}"].TRIGGER] = False
            fast.cycle()
            ref.cycle()
            assert_same(fast, ref, f"command {i} ({type_name} {ops}), cycle {k}")
            most = max(most, laned(fast))
        assert laned(ref) == 0
    return most


#: a jog and two gears (command and actual reference) for random commands to meet
PREAMBLE: list[tuple[str, dict[str, object], int]] = [
    ("MAJ", {"Axis": 1, "Speed": 100.0, "AccelRate": 5000.0, "DecelRate": 5000.0}, 1),
    ("MAG", {"SlaveAxis": 3, "MasterAxis": 1, "Ratio": 0.3, "MasterReference": 1, "Clutch": 1}, 1),
    ("MAG", {"SlaveAxis": 4, "MasterAxis": 1, "Ratio": 0.7, "MasterReference": 0, "Clutch": 1}, 5),
]


@settings(max_examples=80, deadline=None)
@given(script=st.lists(command(), min_size=1, max_size=10))
def test_random_commands_give_the_same_motion_with_and_without_lanes(
    script: list[tuple[str, dict[str, object], int]],
) -> None:
    fast, ref = pair()
    assert run_pair(fast, ref, PREAMBLE, prefix="P") == 3
    run_pair(fast, ref, script)


def test_a_line_shaft_runs_in_the_lanes_and_leaves_them_when_touched() -> None:
    """Two jogging masters; gears on command and actual positions, a rotary slave and a
    slave of a slave (level 1): all steady states are laned, and commands that touch
    them (a speed change, a superimposed move, a stop) give the reference's motion."""
    fast, ref = pair()
    script: list[tuple[str, dict[str, object], int]] = [
        ("MAJ", {"Axis": 1, "Speed": 100.0, "AccelRate": 5000.0, "DecelRate": 5000.0}, 1),
        ("MAJ", {"Axis": 2, "Direction": 1, "Speed": 40.0, "AccelRate": 5000.0,
                 "DecelRate": 5000.0}, 1),
        ("MAG", {"SlaveAxis": 3, "MasterAxis": 1, "Ratio": 0.3, "MasterReference": 1,
                 "Clutch": 1}, 1),
        ("MAG", {"SlaveAxis": 4, "MasterAxis": 2, "Ratio": -1.7, "MasterReference": 0,
                 "Clutch": 1}, 1),
        ("MAG", {"SlaveAxis": 5, "MasterAxis": 3, "Ratio": 2.5, "MasterReference": 1,
                 "Clutch": 0, "AccelRate": 2000.0}, 200),
    ]  # fmt: skip
    assert run_pair(fast, ref, script) == 5
    by_lane = {ax.number: ax.processes[0].lane for ax in fast.ctl.axes[:5]}
    assert by_lane[1] is by_lane[2] is not None  # the jogs
    assert by_lane[3] is by_lane[5] is not by_lane[4]  # command and actual gears
    touch: list[tuple[str, dict[str, object], int]] = [
        # a speed change of a laned jog (MCD re-plans the profile)
        ("MCD", {"Axis": 1, "MotionType": 0, "ChangeSpeed": 1, "Speed": 160.0,
                 "ChangeAccel": 0, "ChangeDecel": 0}, 30),
        # master 2 accelerates slowly; slave 4 follows its actual position in the lane
        ("MAJ", {"Axis": 2, "Direction": 1, "Speed": 400.0, "AccelRate": 100.0,
                 "DecelRate": 100.0}, 20),
        # MC_GearOut mid-acceleration: the slave keeps the gear's velocity of now
        ("MC_GearOut", {"Slave": 4}, 5),
        # a move superimposed on the laned gear of axis 3
        ("MAM", {"Axis": 3, "MoveType": 1, "Position": 5.0, "Speed": 50.0,
                 "AccelRate": 5000.0, "DecelRate": 5000.0}, 80),
        ("MAS", {"Axis": 2, "StopType": 1, "ChangeDecel": 1, "DecelRate": 500.0}, 400),
    ]  # fmt: skip
    run_pair(fast, ref, touch, prefix="T")
    for name in ("T0", "T1", "T2", "T3", "T4"):
        assert not fast.instances[name].outputs.get("ER", False), name
        assert not fast.instances[name].outputs.get("Error", False), name
    ctl = fast.ctl
    assert ctl.axis(1).command_velocity == 160.0
    # the held velocity is the gear's at MC_GearOut: -1.7 x master 2 between its speeds
    # (40 and 400 units/s, reverse direction), not the laned value before the ramp
    held = ctl.axis(4).command_velocity
    assert -1.7 * -400.0 > held > -1.7 * -40.0 + 1.0
    assert ctl.axis(2).command_velocity == 0.0
    # axis 1 jogs, axes 3 and 5 are geared again after the move: laned; 4 holds a velocity
    assert {ax.number for ax in ctl.axes if ax.processes and ax.processes[0].lane} == {1, 3, 5}


def test_by_default_only_groups_of_lane_min_axes_use_the_lanes() -> None:
    """``Controller(lanes=None)``: a group of fewer than LANE_MIN_AXES axes composes in
    Python (cheaper there), a larger one in the lanes; ``lanes=True`` offers them to
    every group (what the tests above compare)."""
    from motion_server.kernel.motion import LANE_MIN_AXES

    def jogging(n_axes: int, lanes: bool | None) -> int:
        cfg = [AxisConfig(k, f"V{k}", AxisType.VIRTUAL) for k in range(1, n_axes + 1)]
        s = MotionSystem(
            Controller(cfg, [GroupConfig(1, "G", tuple(range(1, n_axes + 1)), 0.002)], lanes=lanes)
        )
        for n in range(1, n_axes + 1):
            s.ctl.servo_on(s.ctl.axis(n))
            maj = s.add("MAJ", f"J{n}", {"Axis": n, "Speed": 10.0, "AccelRate": 1e4})
            maj.inputs["Execute"] = True
        s.cycle(5)
        return laned(s)

    assert jogging(LANE_MIN_AXES - 1, None) == 0
    assert jogging(LANE_MIN_AXES, None) == LANE_MIN_AXES
    assert jogging(LANE_MIN_AXES - 1, True) == LANE_MIN_AXES - 1
