"""Idle instances cost nothing: an instance that is asleep is not called, and the
controller behaves bit for bit as if every instance were called every cycle.

The reference is the same map built with ``MotionSystem(sleep=False)``: both systems get
the same writes, and after every cycle every output of every instance and every kernel
array must be identical (floats compared by their bytes)."""

from __future__ import annotations

from typing import Any

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.config import load
from motion_server.instructions import MotionSystem
from motion_server.instructions.schema import Kind, TagType
from motion_server.instructions.status import LogixBit

SITE = load(None, {})
NAMES = [inst.name for inst in SITE.instances()]
#: instances that start, stop and follow motion (drawn as often as all the others)
MOTION = [
    f"{t}_1"
    for t in (
        "MAJ", "MAM", "MAS", "MAG", "MSF", "MSO", "MGS", "MAFR", "MC_Power", "MC_Stop",
        "MC_Halt", "MC_MoveVelocity", "MC_MoveAbsolute", "MC_GearIn", "MC_GearOut",
    )
]  # fmt: skip
OPERANDS = {name: type(inst).OPERANDS for name, inst in SITE.build().instances.items()}


def build(sleep: bool) -> MotionSystem:
    system = SITE.build()
    system.sleep = sleep
    return system


def same(a: MotionSystem, b: MotionSystem, where: str) -> None:
    for name, inst in a.instances.items():
        other = b.instances[name]
        assert repr(dict(inst.outputs)) == repr(dict(other.outputs)), f"{name} {where}"
    sa, sb = a.ctl.arrays, b.ctl.arrays
    for key, arr in vars(sa).items():
        if isinstance(arr, np.ndarray):
            assert arr.tobytes() == getattr(sb, key).tobytes(), f"arrays.{key} {where}"
    for ax, bx in zip(a.ctl.axes, b.ctl.axes, strict=True):
        assert (ax.state, ax.fault, len(ax.processes)) == (bx.state, bx.fault, len(bx.processes))


def value(kind: Kind, type_: TagType) -> st.SearchStrategy[Any]:
    """Operand values that make things happen: axes that exist (and one that does not),
    speeds and distances a demo axis can do, small selectors."""
    if kind == Kind.AXIS:
        return st.one_of(st.integers(1, 3), st.integers(1, 5))
    if kind == Kind.GROUP:
        return st.integers(1, 2)
    if type_ == TagType.BOOL:
        return st.booleans()
    if type_.is_float:
        return st.sampled_from([0.0, 0.5, 1.0, 10.0, 100.0, 500.0, -20.0, 1e4])
    return st.integers(0, 3)


@st.composite
def step(draw: st.DrawFn) -> tuple[str, dict[str, Any], bool | None, int]:
    """(instance, operands to write, trigger level (None: a one-cycle pulse), cycles to
    run after)."""
    name = draw(st.sampled_from(MOTION if draw(st.integers(0, 3)) else NAMES))
    operands = OPERANDS[name]
    chosen = draw(st.lists(st.sampled_from(operands), max_size=3)) if operands else []
    ops = {op.name: draw(value(op.kind, op.type)) for op in chosen}
    level = draw(st.sampled_from([None, None, True, False]))
    return name, ops, level, draw(st.integers(1, 60))


@settings(max_examples=80, deadline=None)
@given(script=st.lists(step(), min_size=1, max_size=30), wheel=st.floats(-500.0, 500.0))
def test_sleeping_changes_nothing(
    script: list[tuple[str, dict[str, Any], bool | None, int]], wheel: float
) -> None:
    a, b = build(sleep=True), build(sleep=False)
    for system in (a, b):  # the three axes a drive can move, on
        for axis in (1, 2, 3):
            system.ctl.servo_on(system.ctl.axis(axis))
    for k, (name, ops, level, cycles) in enumerate(script):
        for system in (a, b):
            inst = system.instances[name]
            for key, v in ops.items():
                inst.inputs[key] = v
            inst.inputs[inst.TRIGGER] = True if level is None else level
            system.ctl.set_feedback_input(system.ctl.axis(4), wheel * k)
        if level is None:
            a.cycle()
            b.cycle()
            same(a, b, f"after the pulse of step {k}")
            a.instances[name].inputs[a.instances[name].TRIGGER] = False
            b.instances[name].inputs[b.instances[name].TRIGGER] = False
        for c in range(cycles):
            a.cycle()
            b.cycle()
            same(a, b, f"after step {k}, cycle {c}")


def test_idle_instances_are_not_called() -> None:
    system = build(sleep=True)
    system.cycle()
    assert system.awake() == []  # nothing triggered: every instance asleep
    maj = system.instances["MAJ_1"]
    maj.inputs["Axis"] = 1  # a write wakes it, even without an edge
    assert system.awake() == [maj]
    system.cycle()
    assert system.awake() == []


def test_a_running_instance_is_followed_until_it_is_done() -> None:
    system = build(sleep=True)
    mso, maj, mas = (system.instances[n] for n in ("MSO_1", "MAJ_1", "MAS_1"))
    for inst, ops in ((mso, {"Axis": 1}), (maj, {"Axis": 1, "Speed": 10.0})):
        for key, v in ops.items():
            inst.inputs[key] = v
        inst.inputs["Execute"] = True
        system.cycle()
        inst.inputs["Execute"] = False
        system.cycle()
    assert maj.outputs["IP"] and not maj.outputs["EN"]
    system.cycle(10)
    # rung low, EN clear, but the jog goes on: parked on it (its state read each cycle)
    assert system.awake() == [] and system.parked() == [maj]
    mas.inputs["Axis"] = 1
    mas.inputs["StopType"] = 0  # all motion
    mas.inputs["Execute"] = True
    system.cycle()
    mas.inputs["Execute"] = False
    # the stop ends the jog: the MAJ that started it no longer shows IP
    system.cycle(2000)
    assert not maj.outputs["IP"] and not mas.outputs["IP"]
    assert system.awake() == [] and system.parked() == []


def test_mc_power_follows_an_axis_switched_on_by_another_instruction() -> None:
    system = build(sleep=True)
    power = system.instances["MC_Power_1"]
    mso = system.instances["MSO_1"]
    power.inputs["Axis"] = 2
    power.inputs["Enable"] = True
    system.cycle()
    power.inputs["Enable"] = False  # off again: the axis is off, the block idle
    system.cycle(3)
    assert power not in system.awake() and not power.outputs["Status"]
    mso.inputs["Axis"] = 2
    mso.inputs["Execute"] = True
    system.cycle()
    # MC_Power's Status follows the axis (its latched Axis 2) though Enable is low
    assert power.outputs["Status"]


def pulse_on(system: MotionSystem, name: str, **operands: Any) -> None:
    """Write ``operands`` and raise ``name``'s rung; it stays high."""
    inst = system.instances[name]
    for key, v in operands.items():
        inst.inputs[key] = v
    inst.inputs[inst.TRIGGER] = True


def test_a_parked_instance_is_not_called_until_a_write_or_its_end() -> None:
    system = build(sleep=True)
    maj = system.instances["MAJ_1"]
    system.ctl.servo_on(system.ctl.axis(1))
    pulse_on(system, "MAJ_1", Axis=1, Speed=10.0)  # the rung held high
    system.cycle(2)
    assert system.parked() == [maj] and maj.outputs["IP"] and maj.outputs["EN"]
    calls: list[str] = []
    scan, update = maj.scan, maj.update
    maj.scan = lambda: (calls.append("scan"), scan())[1]  # type: ignore[method-assign]
    maj.update = lambda: (calls.append("update"), update())[1]  # type: ignore[method-assign]
    system.cycle(60)  # (the default AccelRate: 10 mm/s reached within 100 ms)
    assert calls == [] and maj.outputs["IP"]  # jogging on, nothing to do
    assert system.ctl.axis(1).command_velocity == 10.0
    maj.inputs["Execute"] = False  # the write wakes it: the low rung clears EN
    system.cycle()
    assert calls == ["scan", "update"] and not maj.outputs["EN"] and maj.outputs["IP"]
    assert system.parked() == [maj]  # waiting on the jog again, the rung low and steady


def test_a_group_stop_ends_the_parked_instances_in_its_cycle() -> None:
    """A jog and a gear parked, rungs held high; the group stop aborts both: IP clears in
    the cycle of the stop, the FLAGS word with it, exactly as when every instance is
    called every cycle; then both sleep (their rungs steady)."""
    a, b = build(sleep=True), build(sleep=False)
    for system in (a, b):
        for axis in (1, 2):
            system.ctl.servo_on(system.ctl.axis(axis))
        pulse_on(system, "MAJ_1", Axis=1, Speed=50.0)
        pulse_on(system, "MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5)
    for c in range(30):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c}")
    maj, mag = a.instances["MAJ_1"], a.instances["MAG_1"]
    assert set(a.parked()) == {maj, mag} and maj.outputs["IP"] and mag.outputs["IP"]
    for system in (a, b):
        pulse_on(system, "MGS_1", Group=1, StopMode=1)  # Fast Stop of Group1
    a.cycle()
    b.cycle()
    same(a, b, "the cycle of the stop")
    for inst in (maj, mag):
        assert not inst.outputs["IP"] and inst.outputs["DN"] and inst.outputs["EN"]
        assert inst.outputs["FLAGS"] & (1 << LogixBit.IP.value) == 0
    assert a.parked() == [] and maj not in a.awake() and mag not in a.awake()
    for c in range(200):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c} after the stop")


def test_only_logix_instances_that_wait_on_nothing_but_their_process_park() -> None:
    """A type parks (``PARKS``) only if its scan, update and poll are those whose
    parked state :meth:`ProcessInstruction.end_parked` knows: a type that follows more
    than its process's state (a cam's SEGMENT) or overrides them must say False."""
    from motion_server.instructions.base import LogixInstruction
    from motion_server.instructions.logix.mdsc import SpeedControlledMotion
    from motion_server.instructions.logix_common import ProcessInstruction
    from motion_server.instructions.registry import catalog

    parking = {name for name, cls in catalog().items() if getattr(cls, "PARKS", False)}
    assert {"MAJ", "MAM", "MAG", "MAS"} <= parking
    assert not parking & {"MAPC", "MATC"}
    for name in parking:
        cls = catalog()[name]
        assert issubclass(cls, ProcessInstruction), name
        assert cls.scan is LogixInstruction.scan and cls.update is LogixInstruction.update
        assert cls.poll in (ProcessInstruction.poll, SpeedControlledMotion.poll), name


def test_parked_instances_round_trip_through_a_snapshot() -> None:
    """A system restored from its state keeps its parked instances on the restored
    processes: a group stop then ends them as it ends the original's."""
    from motion_server.scan import statecodec

    a = build(sleep=True)
    for axis in (1, 2):
        a.ctl.servo_on(a.ctl.axis(axis))
    pulse_on(a, "MAJ_1", Axis=1, Speed=50.0)
    pulse_on(a, "MAG_1", SlaveAxis=2, MasterAxis=1, Ratio=0.5)
    a.cycle(30)
    b = statecodec.loads(statecodec.dumps(a))
    assert [i.name for i in b.parked()] == [i.name for i in a.parked()] == ["MAG_1", "MAJ_1"]
    for system in (a, b):
        pulse_on(system, "MGS_1", Group=1, StopMode=1)
    for c in range(100):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c} after the stop")
    assert b.parked() == [] and not b.instances["MAJ_1"].outputs["IP"]


def test_a_plcopen_move_parks_while_busy_and_sleeps_on_its_held_done() -> None:
    """MC_MoveRelative with Execute held high (PLCopen holds Done until it falls):
    parked while the move runs, Done shown in the cycle the move ends, then asleep
    while Execute stays high; Execute low releases Done in the next cycle, exactly as
    with every instance called every cycle."""
    a, b = build(sleep=True), build(sleep=False)
    move = {"Axis": 1, "Distance": 5.0, "Velocity": 50.0, "Acceleration": 1000.0,
            "Deceleration": 1000.0}  # fmt: skip
    for system in (a, b):
        system.ctl.servo_on(system.ctl.axis(1))
        pulse_on(system, "MC_MoveRelative_1", **move)
    block = a.instances["MC_MoveRelative_1"]
    parked = done = 0
    for c in range(200):  # 5 units at 50 units/s, 1,000 units/s²: 150 ms, 75 cycles
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c}")
        parked += block in a.parked()
        done += bool(block.outputs["Done"])
    assert parked > 50 and done > 100 and block.outputs["Done"]
    assert a.awake() == [] and a.parked() == []  # Done held: nothing left to call
    for system in (a, b):
        system.instances["MC_MoveRelative_1"].inputs["Execute"] = False
    for c in range(3):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c} after Execute fell")
    assert not block.outputs["Done"] and not block.outputs["Busy"]


def test_only_plcopen_blocks_that_show_nothing_while_busy_park() -> None:
    """MotionBlock.parked_on and PLCopenBlock's held terminal state apply only to types
    whose scan, update, poll and publish are the shared ones: a block that shows more
    (InVelocity, InGear, InSync) or drops a latch in its scan is called every cycle."""
    from motion_server.instructions.base import PLCopenBlock, _holds_terminal
    from motion_server.instructions.plcopen_common import MotionBlock, _parks
    from motion_server.instructions.registry import catalog

    blocks = {n: c for n, c in catalog().items() if issubclass(c, MotionBlock)}
    parking = {n for n, c in blocks.items() if _parks(c)}
    assert {"MC_MoveAbsolute", "MC_MoveRelative", "MC_MoveAdditive", "MC_Halt"} <= parking
    assert not parking & {"MC_MoveVelocity", "MC_GearIn", "MC_CamIn", "MC_Stop"}
    plcopen = {n: c for n, c in catalog().items() if issubclass(c, PLCopenBlock)}
    holding = {n for n, c in plcopen.items() if _holds_terminal(c)}
    assert {"MC_MoveAbsolute", "MC_GearIn", "MC_CamIn"} <= holding
    assert not holding & {"MC_Stop", "MC_Power", "MC_MoveVelocity"}


def test_a_parked_move_velocity_wakes_when_an_override_takes_its_speed() -> None:
    """MC_MoveVelocity at speed with InVelocity shown parks on its jog. MC_SetOverride
    at 50 % re-plans the jog (no longer at speed): InVelocity drops in that very cycle,
    and rises again once the jog reaches the new speed, exactly as with every instance
    called every cycle."""
    a, b = build(sleep=True), build(sleep=False)
    run = {"Axis": 1, "Velocity": 100.0, "Acceleration": 1000.0, "Deceleration": 1000.0}
    for system in (a, b):
        system.ctl.servo_on(system.ctl.axis(1))
        pulse_on(system, "MC_MoveVelocity_1", **run)
    block = a.instances["MC_MoveVelocity_1"]
    for c in range(100):  # 100 units/s at 1,000 units/s²: 0.1 s, 50 cycles
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c}")
    assert a.parked() == [block] and block.outputs["InVelocity"]
    for system in (a, b):
        system.instances["MC_SetOverride_1"].inputs.update({"Axis": 1, "VelFactor": 0.5})
        system.instances["MC_SetOverride_1"].inputs["Enable"] = True
    shown = []
    for c in range(100):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c} with the override")
        shown.append(bool(block.outputs["InVelocity"]))
    assert shown[0] is False and shown[-1] is True  # left its speed, then reached 50
    assert a.ctl.axis(1).command_velocity == 50.0 and a.parked() == [block]


def test_a_locked_gear_in_parks_until_another_command_aborts_it() -> None:
    """MC_GearIn of Axis2 to Axis1 (jogging) parks once InGear shows; MC_Halt of Axis2
    aborts the gear: CommandAborted and InGear cleared in that cycle, as with every
    instance called every cycle."""
    a, b = build(sleep=True), build(sleep=False)
    for system in (a, b):
        for axis in (1, 2):
            system.ctl.servo_on(system.ctl.axis(axis))
        pulse_on(system, "MAJ_1", Axis=1, Speed=20.0)
        pulse_on(system, "MC_GearIn_1", Slave=2, Master=1, RatioNumerator=1.0,
                 RatioDenominator=2.0, Acceleration=1000.0, Deceleration=1000.0)  # fmt: skip
    gear = a.instances["MC_GearIn_1"]
    for c in range(200):
        a.cycle()
        b.cycle()
        same(a, b, f"cycle {c}")
    assert gear.outputs["InGear"] and gear in a.parked()
    for system in (a, b):
        pulse_on(system, "MC_Halt_1", Axis=2, Deceleration=1000.0)
    a.cycle()
    b.cycle()
    same(a, b, "the cycle of the halt")
    assert gear.outputs["CommandAborted"] and not gear.outputs["InGear"]
    assert gear not in a.parked()
