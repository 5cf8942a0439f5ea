"""The scan on its own: what it publishes after every cycle, how it contains a failing
instruction, and what it does with writes a front-end should never have sent."""

from __future__ import annotations

import logging
import random

import numpy as np
import pytest

from motion_server import config
from motion_server.image import wire
from motion_server.instructions.logix.maj import MAJ
from motion_server.instructions.plcopen.mc_move_velocity import MC_MoveVelocity
from motion_server.kernel import ErrorCode
from motion_server.runtime import Runtime
from motion_server.safety.client import ClientInfo
from motion_server.tagmap import ClockMode

SITE = """
[site]
name = "scan_test"

[controller]
clock = "manual"
status_log_interval = 0.0

[modbus]
enabled = false

[opcua]
enabled = false

[[groups]]
name = "Group1"
coarse_update_period_ms = 2.0
axes = ["Axis1", "Axis2", "Axis3", "Wheel"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis2"
type = "servo"
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0

[[axes]]
name = "Axis3"
type = "servo"
rollover = 360.0
units = "deg"

[[axes]]
name = "Wheel"
type = "feedback_only"
conversion_constant = 100.0

[instructions]
every_type = true

[[watchdogs]]
name = "HMI1"
timeout = 1.0
group = "Group1"
"""


def site() -> config.SiteMap:
    return config.parse(SITE, "scan-test.toml")


def published_equals_getters(rt: Runtime) -> None:
    """Every slot of the published image equals what the system's getters read now."""
    snap = rt.image.snapshot()
    getter = rt.scan.image.getter
    expected = np.array([float(getter(t.name)()) for t in rt.layout.tags])
    differ = np.flatnonzero(
        ~((snap.values == expected) | (np.isnan(snap.values) & np.isnan(expected)))
    )
    assert differ.size == 0, [
        (rt.layout.tags[i].name, snap.values[i], expected[i]) for i in differ[:10]
    ]


#: (instance, operand choices) a random scenario picks from
MOVES: list[tuple[str, dict[str, list[float]]]] = [
    ("MSO_1", {"Axis": [1, 2, 3]}),
    ("MSF_1", {"Axis": [2, 3]}),
    ("MAJ_1", {"Axis": [1, 2, 3], "Speed": [0.0, 10.0, 250.0], "Direction": [0, 1]}),
    ("MAJ_1", {"Axis": [1, 2, 3], "Speed": [40.0, 250.0], "AccelRate": [500.0, 5000.0]}),
    (
        "MAM_1",
        {"Axis": [1, 2, 3], "Position": [-20.0, 5.5, 400.0], "Speed": [50.0, 400.0]}
        | {"AccelRate": [1000.0], "DecelRate": [1000.0], "MoveType": [0, 1]},
    ),
    ("MAS_1", {"Axis": [1, 2, 3], "StopType": [0, 1, 2]}),
    ("MAG_1", {"SlaveAxis": [2, 3], "MasterAxis": [1], "Ratio": [0.5, -2.0]}),
    ("MGS_1", {"Group": [1], "StopMode": [0, 1, 2]}),
    ("MAFR_1", {"Axis": [1, 2, 3]}),
    ("MC_Power_1", {"Axis": [1, 2]}),
    ("MC_MoveVelocity_1", {"Axis": [1, 2], "Velocity": [30.0, 90.0]}),
    ("MC_Halt_1", {"Axis": [1, 2]}),
    ("MC_GearIn_1", {"Master": [1], "Slave": [2, 3], "RatioNumerator": [1, 3]}),
    ("HMI1", {}),
]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_image_equals_the_system_after_every_cycle(seed: int) -> None:
    """Only what changed is copied into the image each cycle (instruction outputs of the
    instances that changed, written operands); a random mix of commands checks that
    nothing is missed: after every cycle the published image equals a full read."""
    r = random.Random(seed)
    rt = Runtime(site())
    published_equals_getters(rt)
    for _ in range(400):
        name, choices = r.choice(MOVES)
        if name == "HMI1":
            rt.image.write("HMI1.Heartbeat", r.randrange(1000))
        elif r.random() < 0.3:
            rt.image.write(f"{name}.{'Enable' if name == 'MC_Power_1' else 'Execute'}", False)
        else:
            ops = {f"{name}.{k}": r.choice(v) for k, v in choices.items()}
            trigger = "Enable" if name == "MC_Power_1" else "Execute"
            rt.image.write_many([*ops.items(), (f"{name}.{trigger}", True)])
        if r.random() < 0.2:
            rt.image.write("Wheel.FeedbackInput", r.uniform(-50.0, 50.0))
        published_equals_getters(rt)  # writes applied at once (manual clock)
        rt.cycle(r.randrange(1, 6))
        published_equals_getters(rt)


class _FailingJog(MAJ):
    """A jog that starts its motion, then raises (a bug in an instruction)."""

    def execute(self) -> None:
        super().execute()
        raise RuntimeError("deliberate failure")


class _FailingMoveVelocity(MC_MoveVelocity):
    def execute(self) -> None:
        super().execute()
        raise ZeroDivisionError("deliberate failure")


def test_a_failing_instruction_shows_the_internal_error_and_stops_its_axis(
    caplog: pytest.LogCaptureFixture,
) -> None:
    s = site()
    system = s.build()
    for name, cls in (("MAJ_1", _FailingJog), ("MC_MoveVelocity_1", _FailingMoveVelocity)):
        defaults = dict(system.instances.pop(name).inputs)
        defaults.pop(cls.TRIGGER)
        system.adopt(cls(name, system.ctl, defaults))
    rt = Runtime(s, system=system)
    for axis in (1, 2):
        rt.image.write_many([("MSO_1.Axis", axis), ("MSO_1.Execute", True)])
        rt.cycle()
        rt.image.write("MSO_1.Execute", False)
        rt.cycle()
    # Axis2 moves by an instruction that works: MAM, 100 mm at 500 mm/s
    rt.image.write_many([("MAM_1.Axis", 2), ("MAM_1.Position", 100.0), ("MAM_1.Speed", 500.0)])
    rt.image.write_many([("MAM_1.AccelRate", 5000.0), ("MAM_1.DecelRate", 5000.0)])
    rt.image.write("MAM_1.Execute", True)
    rt.cycle()
    with caplog.at_level(logging.ERROR, logger="motion_server.scan"):
        rt.image.write_many([("MAJ_1.Axis", 1), ("MAJ_1.Speed", 100.0), ("MAJ_1.Execute", True)])
        rt.cycle()
    assert rt.image.read("MAJ_1.ER") and not rt.image.read("MAJ_1.IP")
    assert rt.image.read("MAJ_1.ERR") == ErrorCode.INTERNAL_ERROR == 1005
    failures = [r for r in caplog.records if "MAJ_1" in r.getMessage()]
    assert len(failures) == 1 and failures[0].exc_info is not None  # logged once, traceback
    # its axis stops (the jog had begun: a ramp at the axis's 5000 mm/s² to rest)
    rt.cycle(20)
    assert rt.ctl.axis(1).command_velocity == 0.0
    assert not rt.ctl.axis(1).moving
    # every other instance and axis went on: MAM reaches its target
    rt.cycle(200)
    assert rt.image.read("MAM_1.PC") and rt.ctl.axis(2).command_position == 100.0
    # the PLCopen dialect: Error and ErrorID
    rt.image.write_many([("MC_MoveVelocity_1.Axis", 2), ("MC_MoveVelocity_1.Velocity", 50.0)])
    rt.image.write("MC_MoveVelocity_1.Execute", True)
    rt.cycle()
    assert rt.image.read("MC_MoveVelocity_1.Error")
    assert not rt.image.read("MC_MoveVelocity_1.Busy")
    assert rt.image.read("MC_MoveVelocity_1.ErrorID") == 1005
    rt.cycle(50)
    assert rt.ctl.axis(2).command_velocity == 0.0
    assert rt.image.read("Clock.Cycle") == rt.ctl.tick  # the scan ran throughout


def test_the_scan_refuses_what_a_front_end_should_never_send() -> None:
    """A batch naming a status tag or a slot outside the image (a front-end that was
    compromised, or built from another map) is refused whole, and nothing changes."""
    rt = Runtime(site())
    ch = rt._local.channel
    speed = rt.layout.slot("MAJ_1.Speed")
    for bad in (rt.layout.slot("MAJ_1.DN"), rt.layout.size + 5):
        ticket = rt._local.send([(speed, 42.0), (bad, 1.0)], ClientInfo("modbus", "10.9.9.9"))
        assert ticket.ack is not None and ticket.ack.result == wire.Result.REFUSED
        assert rt.system.instances["MAJ_1"].inputs["Speed"] != 42.0
        assert ch.number == 3


def test_a_clock_step_during_the_programmed_stop_is_answered_at_once() -> None:
    """The programmed stop runs its own cycles; a Clock.Step written meanwhile is
    answered (NOT_RUN) instead of waiting for cycles that will never come."""
    rt = Runtime(site())
    rt.image.write_many([("MSO_1.Axis", 1), ("MSO_1.Execute", True)])
    rt.cycle(2)
    rt.image.write_many([("MAJ_1.Axis", 1), ("MAJ_1.Speed", 400.0), ("MAJ_1.Execute", True)])
    rt.cycle(50)
    rt.image.write("Clock.StepCycles", 10)
    rt.request_stop()  # the stop begins with the next pass, the one the write causes
    ticket = rt.image.write("Clock.Step", True)
    assert ticket.ack is not None and ticket.ack.result == wire.Result.NOT_RUN
    assert rt.scan.finished and rt.ctl.axis(1).command_velocity == 0.0


@pytest.mark.parametrize("mode", [ClockMode.FAST, ClockMode.REALTIME])
def test_a_clock_mode_written_takes_effect_at_once(mode: ClockMode) -> None:
    """The manual clock waits for writes, with nothing due before its next timer (the
    load window: a second). A write that switches the clock asks to be called again at
    once, so the first cycles of the new mode do not wait for that timer."""
    rt = Runtime(site())
    scan = rt.scan
    scan.start(0.0)
    assert scan.service(0.5) == pytest.approx(1.0)  # manual, idle: the next timer
    slot = rt.layout.slot("Clock.Mode")
    scan.deliver(rt._local.channel, wire.Batch(1, ClientInfo("modbus", "10.0.0.1"), [(slot, mode)]))
    tick = rt.ctl.tick
    assert scan.service(0.5) == 0.5
    assert scan.mode == mode and rt.ctl.tick == tick
    scan.service(0.5)
    assert rt.ctl.tick > tick
