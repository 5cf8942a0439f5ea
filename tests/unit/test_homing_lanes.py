"""Homing and redefined positions change nothing between the fast lanes and the
reference path (``Controller(lanes=False)``): the homing process stays out of the lanes,
and a redefinition takes the axis and its followers out of them before it shifts their
coordinates (their lanes copied those values)."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.instructions import MotionSystem, instruction_type
from motion_server.kernel import AxisConfig, AxisType, Controller, GroupConfig
from motion_server.kernel.enums import HomeSequence

from .test_lanes import PREAMBLE, assert_same, pair, run_pair, value

HOMED_AXES = [
    AxisConfig(
        1,
        "V1",
        AxisType.VIRTUAL,
        max_acceleration=5000.0,
        max_deceleration=5000.0,
        home_sequence=HomeSequence.SWITCH_THEN_MARKER,
        home_speed=50.0,
        home_return_speed=5.0,
        home_acceleration=1000.0,
        home_deceleration=1000.0,
        home_switch=30.0,
        home_switch_width=10.0,
        marker_interval=2.5,
        marker_offset=0.3,
        home_position=10.0,
    ),
    AxisConfig(2, "S2", AxisType.SERVO, following_error_limit=1e6),
    AxisConfig(3, "S3", AxisType.SERVO, following_error_limit=1e6),
    AxisConfig(4, "V4", AxisType.VIRTUAL),
    AxisConfig(6, "W6", AxisType.FEEDBACK_ONLY),  # the hand wheel run_pair turns
]


def homing_pair() -> tuple[MotionSystem, MotionSystem]:
    out = []
    for lanes in (True, False):
        group = GroupConfig(1, "G", (1, 2, 3, 4, 6), 0.002)
        s = MotionSystem(Controller(list(HOMED_AXES), [group], lanes=lanes))
        for n in (1, 2, 3, 4):
            s.ctl.servo_on(s.ctl.axis(n))
        out.append(s)
    return out[0], out[1]


def test_homing_a_master_with_laned_followers_matches_the_reference() -> None:
    """A master homes (switch then marker, bidirectional) while a slave follows its
    command and another its actual position, a jog runs beside them, and the slave is
    redefined on the way: bit for bit the reference's motion."""
    fast, ref = homing_pair()
    script: list[tuple[str, dict[str, object], int]] = [
        ("MAJ", {"Axis": 4, "Speed": 20.0, "AccelRate": 500.0, "DecelRate": 500.0}, 1),
        ("MAG", {"SlaveAxis": 2, "MasterAxis": 1, "Ratio": 0.5, "MasterReference": 1,
                 "Clutch": 1}, 1),
        ("MAG", {"SlaveAxis": 3, "MasterAxis": 1, "Ratio": -2.0, "MasterReference": 0,
                 "Clutch": 1}, 1),
        ("MAJ", {"Axis": 1, "Speed": 10.0, "AccelRate": 500.0, "DecelRate": 500.0}, 100),
        ("MAH", {"Axis": 1}, 400),
        ("MRP", {"Axis": 2, "Type": 1, "PositionSelect": 0, "Position": 3.5}, 200),
        ("MC_SetPosition", {"Axis": 4, "Position": -7.0}, 2000),
    ]  # fmt: skip
    assert run_pair(fast, ref, script) >= 3
    mah = fast.instances["I4"]
    assert mah.outputs["PC"] and not mah.outputs["ER"]
    for s in (fast, ref):
        assert s.ctl.axis(1).command_position == 10.0
        assert s.ctl.axis(1).homed
    # the jog and the follower of the actual position are back in their lanes
    assert fast.ctl.axis(3).processes[0].lane is not None
    assert fast.ctl.axis(4).processes[0].lane is not None


MIX = (
    "MAJ",
    "MAG",
    "MAM",
    "MAS",
    "MC_GearIn",
    "MC_MoveVelocity",
    "MC_Stop",
    "MRP",
    "MRP",
    "MC_SetPosition",
    "MC_SetPosition",
    "MAH",
    "MC_Home",
)


@st.composite
def command(draw: st.DrawFn) -> tuple[str, dict[str, object], int]:
    type_name = draw(st.sampled_from(MIX))
    cls = instruction_type(type_name)
    ops = {op.name: draw(value(op)) for op in cls.OPERANDS}
    return type_name, ops, draw(st.integers(1, 60))


@settings(max_examples=60, deadline=None)
@given(script=st.lists(command(), min_size=1, max_size=10))
def test_random_redefinitions_give_the_same_motion_with_and_without_lanes(
    script: list[tuple[str, dict[str, object], int]],
) -> None:
    """Redefinitions (MRP, MC_SetPosition, immediate MAH and MC_Home) of masters,
    slaves and laned axes amid random commands: the lanes agree with the reference."""
    fast, ref = pair()
    run_pair(fast, ref, PREAMBLE, prefix="P")
    run_pair(fast, ref, script)
    assert_same(fast, ref, "end")
