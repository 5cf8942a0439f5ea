"""A small camming bench for the cam tests: a hand-wheel master whose positions the test
sets exactly, servo slaves, and cam tables whose values are worked by hand."""

from __future__ import annotations

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    CamTableConfig,
    Controller,
    GroupConfig,
    MotionStatusBit,
)

from ..support import trigger

L, C = 0, 1  # SegmentType linear, cubic

#: number -> (name, points): every value below is chosen so that linear segments give
#: exact binary fractions
TABLES: dict[int, tuple[str, tuple[tuple[float, float, int], ...]]] = {
    # slope 1/2 over 0..100, flat 100..200 (rise 50 per pass)
    1: ("Half", ((0.0, 0.0, L), (100.0, 50.0, L), (200.0, 50.0, L))),
    # the smooth step over 0..100 (3u^2 - 2u^3)
    2: ("Step", ((0.0, 0.0, C), (100.0, 100.0, C))),
    # the straight line y = x over 0..100
    3: ("Line", ((0.0, 0.0, L), (100.0, 100.0, L))),
    # a profile slot of two points (ERR 27)
    4: ("Short", ((0.0, 0.0, L), (1.0, 1.0, L))),
    # Delta's example: a 360 master table whose slave goes 0..120
    5: ("Delta", ((0.0, 0.0, L), (360.0, 120.0, L))),
    # a time cam: 10 units in 1 s
    6: ("Time", ((0.0, 0.0, L), (1.0, 10.0, L))),
    # a full turn on a rotary slave
    7: ("Turn", ((0.0, 0.0, L), (360.0, 360.0, L))),
}
CAPACITY = {4: 2}


def cam_system(lanes: bool | None = None) -> MotionSystem:
    """Axis 1 hand wheel (master), 2 and 3 linear servo slaves, 4 rotary servo (360), 5
    rotary hand wheel (360), 6 virtual; the tables of :data:`TABLES`; all servos on."""
    axes = [
        AxisConfig(1, "Wheel", AxisType.FEEDBACK_ONLY),
        AxisConfig(2, "Slave", AxisType.SERVO),
        AxisConfig(3, "Slave2", AxisType.SERVO),
        AxisConfig(4, "Knife", AxisType.SERVO, rollover=360.0),
        AxisConfig(5, "Dial", AxisType.FEEDBACK_ONLY, rollover=360.0),
        AxisConfig(6, "Virtual", AxisType.VIRTUAL),
    ]
    cams = [
        CamTableConfig(n, name, CAPACITY.get(n, 8), points) for n, (name, points) in TABLES.items()
    ]
    ctl = Controller(axes, [GroupConfig(1, "G", (1, 2, 3, 4, 5, 6), 0.002)], lanes, cams)
    for n in (2, 3, 4, 6):
        ctl.servo_on(ctl.axis(n))
    return MotionSystem(ctl)


def run(s: MotionSystem, inst: Instruction, **operands: object) -> Instruction:
    """Trigger ``inst`` with ``operands`` (one cycle), then lower its trigger."""
    trigger(s, inst, **operands)
    inst.inputs[inst.TRIGGER] = False
    return inst


def new(s: MotionSystem, type_name: str, **operands: object) -> Instruction:
    """A fresh instance of ``type_name``, triggered with ``operands``."""
    name = f"{type_name}_{len(s.instances)}"
    return run(s, s.add(type_name, name, {}), **operands)


def calc(s: MotionSystem, cam: int, length: int | None = None) -> Instruction:
    """MCCP of table ``cam`` into its own profile."""
    n = len(TABLES[cam][1]) if length is None else length
    inst = new(s, "MCCP", Cam=cam, Length=n, CamProfile=cam)
    assert inst.outputs["DN"] and not inst.outputs["ER"], inst.outputs
    return inst


def master_to(s: MotionSystem, position: float, axis: int = 1) -> None:
    """The hand wheel reads ``position`` from the next cycle on; one cycle runs."""
    s.ctl.set_feedback_input(s.ctl.axis(axis), position)
    s.cycle()


def slave(s: MotionSystem, axis: int = 2) -> float:
    return s.ctl.axis(axis).command_position_unwound


def bit(s: MotionSystem, axis: int, b: MotionStatusBit) -> bool:
    return bool(s.ctl.axis(axis).motion_status >> int(b) & 1)
