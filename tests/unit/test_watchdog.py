"""Communication watchdog: the stop timing in cycles, the latch, the required reset.

First principles used below: period dt = 2 ms and T = 0.1 s give T/dt = 50 cycles. A beat
written between cycles is stamped with the count of completed cycles; the 50 cycles after
it run normally and the 51st (which starts exactly T after the beat) runs the stop, so
the stop starts within T + one cycle. The group stop ramps at the axis maximum
deceleration, 1000 mm/s², trapezoidal: from the jog speed 10 mm/s the commanded velocity
drops by 1000 · 0.002 = 2 mm/s per cycle and reaches 0 after 10/2 = 5 cycles.
"""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.kernel import AxisState, ErrorCode, MotionError, ProgrammedStopMode
from motion_server.runtime import Runtime
from motion_server.safety import ClientInfo, writing_as
from motion_server.safety.watchdog import WATCHDOG_FAULT, WatchdogState

T_CYCLES = 50

SITE = """
[controller]
clock = "manual"
status_log_interval = 0.0

[[groups]]
name = "Group1"
axes = ["Axis1", "Wheel"]

[[axes]]
name = "Axis1"
type = "virtual"
max_velocity = 100.0
max_acceleration = 1000.0
max_deceleration = 1000.0
programmed_stop_mode = "{programmed}"

[[axes]]
name = "Wheel"
type = "feedback_only"

[[instructions.instances]]
name = "MSO_1"
type = "MSO"

[[instructions.instances]]
name = "MAJ_1"
type = "MAJ"

[[instructions.instances]]
name = "MAFR_1"
type = "MAFR"

[[watchdogs]]
name = "HMI1"
timeout = 0.1
group = "Group1"
stop_mode = "{stop_mode}"
per_connection = {per_connection}
"""

HMI_A = ClientInfo("modbus", "10.0.0.1", 50001, connection=1)
HMI_B = ClientInfo("modbus", "10.0.0.2", 50002, connection=2)


def runtime(
    stop_mode: str = "fast_stop", programmed: str = "fast_stop", per_connection: bool = False
) -> Runtime:
    text = SITE.format(
        stop_mode=stop_mode, programmed=programmed, per_connection=str(per_connection).lower()
    )
    return Runtime(config.parse(text, "watchdog-test.toml"))


def pulse(rt: Runtime, instance: str, **operands: float) -> None:
    """Operands, then a rising edge of the trigger, through the tag image; one cycle."""
    for name, value in operands.items():
        rt.image.write(f"{instance}.{name}", value)
    rt.image.write(f"{instance}.Execute", False)
    rt.cycle()
    rt.image.write(f"{instance}.Execute", True)
    rt.cycle()


def jogging(rt: Runtime) -> None:
    """Axis1 enabled and jogging at 10 mm/s (reached after 10/1000 s = 5 cycles)."""
    pulse(rt, "MSO_1", Axis=1)
    pulse(rt, "MAJ_1", Axis=1, Speed=10.0, AccelRate=1000.0, AccelUnits=0, DecelUnits=0)
    rt.cycle(10)
    assert rt.ctl.axis(1).command_velocity == pytest.approx(10.0)


def beat(rt: Runtime, value: int, client: ClientInfo = HMI_A) -> None:
    with writing_as(client):
        rt.image.write("HMI1.Heartbeat", value)


def test_the_stop_starts_in_the_cycle_that_begins_t_after_the_last_beat() -> None:
    rt = runtime()
    ax = rt.ctl.axis(1)
    jogging(rt)
    beat(rt, 1)
    assert rt.image.read("HMI1.State") == WatchdogState.ARMED
    rt.cycle(T_CYCLES)  # T has passed, but no cycle has started after it yet
    assert rt.image.read("HMI1.Age") == T_CYCLES
    assert ax.command_velocity == pytest.approx(10.0)
    assert not rt.image.read("HMI1.Fault")
    rt.cycle()  # starts at T: the stop acts in it
    assert rt.image.read("HMI1.Fault")
    assert rt.image.read("HMI1.State") == WatchdogState.STOPPING
    assert rt.image.read("HMI1.Trips") == 1
    assert ax.command_velocity == pytest.approx(8.0)
    rt.cycle(4)
    assert ax.command_velocity == pytest.approx(0.0, abs=1e-12)


def test_beats_keep_it_armed_and_a_beat_restarts_the_count() -> None:
    rt = runtime()
    jogging(rt)
    for k in range(1, 11):  # ten beats, 49 cycles apart: never T without one
        beat(rt, k)
        rt.cycle(T_CYCLES - 1)
    assert rt.image.read("HMI1.State") == WatchdogState.ARMED
    assert rt.ctl.axis(1).command_velocity == pytest.approx(10.0)
    beat(rt, 10)  # the same value is not a change: the count goes on from beat 10
    rt.cycle(2)
    assert rt.image.read("HMI1.Fault")


def test_without_a_first_beat_the_watchdog_stays_idle() -> None:
    rt = runtime()
    jogging(rt)
    rt.cycle(10 * T_CYCLES)
    assert rt.image.read("HMI1.State") == WatchdogState.IDLE
    assert rt.ctl.axis(1).command_velocity == pytest.approx(10.0)


def stopped_and_latched(rt: Runtime) -> None:
    jogging(rt)
    beat(rt, 1)
    rt.cycle(T_CYCLES + 1 + 5)  # trip, 5 cycles of ramp
    rt.cycle()  # the check before this cycle sees the stop complete: latch
    assert rt.image.read("HMI1.State") == WatchdogState.FAULTED


def test_the_latch_faults_the_axes_and_a_returning_heartbeat_changes_nothing() -> None:
    rt = runtime()
    ax, wheel = rt.ctl.axis(1), rt.ctl.axis(2)
    stopped_and_latched(rt)
    assert ax.state == AxisState.AXIS_FAULTED
    assert rt.image.read("Axis1.AxisFault") == WATCHDOG_FAULT
    assert wheel.fault == 0  # a hand wheel is not faulted
    for k in range(2, 6):  # the client is back and beats again
        beat(rt, k)
        rt.cycle(10)
    assert rt.image.read("HMI1.Fault")
    assert rt.image.read("HMI1.State") == WatchdogState.FAULTED
    # the jog's Execute is still high: re-writing it is no edge, nothing moves
    rt.image.write("MAJ_1.Execute", True)
    rt.cycle(10)
    assert ax.command_velocity == 0.0
    # a new edge is refused: the axis is faulted (ERR 20) until the reset
    pulse(rt, "MAJ_1")
    assert rt.image.read("MAJ_1.ER")
    assert rt.image.read("MAJ_1.ERR") == 20
    assert ax.command_velocity == 0.0


def test_the_reset_tag_clears_the_latch_and_motion_needs_new_commands() -> None:
    rt = runtime()
    ax = rt.ctl.axis(1)
    stopped_and_latched(rt)
    rt.image.write("HMI1.Reset", True)
    rt.cycle(20)
    assert rt.image.read("HMI1.State") == WatchdogState.IDLE
    assert not rt.image.read("HMI1.Fault")
    assert ax.state == AxisState.AXIS_READY
    assert ax.fault == 0
    assert ax.command_velocity == 0.0  # nothing restarted by itself
    pulse(rt, "MSO_1", Axis=1)
    pulse(rt, "MAJ_1", Axis=1)
    rt.cycle(10)
    assert ax.command_velocity == pytest.approx(10.0)


def test_mafr_on_the_axes_clears_the_latch_too() -> None:
    rt = runtime()
    stopped_and_latched(rt)
    pulse(rt, "MAFR_1", Axis=1)
    rt.cycle()
    assert rt.image.read("HMI1.State") == WatchdogState.IDLE
    assert rt.ctl.axis(1).state == AxisState.AXIS_READY


def test_a_reset_while_the_group_is_stopping_is_ignored() -> None:
    rt = runtime()
    jogging(rt)
    beat(rt, 1)
    rt.cycle(T_CYCLES + 2)  # tripped, ramp under way
    rt.image.write("HMI1.Reset", True)
    rt.image.write("HMI1.Reset", False)
    assert rt.image.read("HMI1.State") == WatchdogState.STOPPING
    rt.cycle(10)
    assert rt.image.read("HMI1.State") == WatchdogState.FAULTED


def test_fast_disable_and_programmed_hard_disable() -> None:
    # fast disable: the same 2 mm/s-per-cycle ramp, then the drive off (faulted)
    rt = runtime(stop_mode="fast_disable")
    jogging(rt)
    beat(rt, 1)
    rt.cycle(T_CYCLES + 1)
    assert rt.ctl.axis(1).command_velocity == pytest.approx(8.0)
    assert rt.ctl.axis(1).state == AxisState.SERVO_CONTROL
    # programmed with the axis's hard disable: the drive goes off in the trip cycle
    rt = runtime(stop_mode="programmed", programmed="hard_disable")
    jogging(rt)
    beat(rt, 1)
    rt.cycle(T_CYCLES)
    assert rt.ctl.axis(1).state == AxisState.SERVO_CONTROL
    rt.cycle()
    assert rt.ctl.axis(1).state == AxisState.AXIS_READY


def test_per_connection_a_live_hmi_does_not_cover_for_a_dead_one() -> None:
    rt = runtime(per_connection=True)
    jogging(rt)
    beat(rt, 1, HMI_A)
    beat(rt, 1, HMI_B)  # the same value from another connection: its first beat
    for k in range(2, 5):  # B goes on beating every 25 cycles; A is silent
        rt.cycle(25)
        beat(rt, k, HMI_B)
    # A's last beat was 75 cycles ago: the check before the 51st cycle tripped
    assert rt.image.read("HMI1.Fault")
    assert rt.image.read("HMI1.Trips") == 1


def test_per_connection_trip_timing_counts_from_the_silent_connection() -> None:
    rt = runtime(per_connection=True)
    jogging(rt)
    beat(rt, 7, HMI_A)
    rt.cycle(30)
    beat(rt, 7, HMI_B)
    rt.cycle(T_CYCLES - 30)
    assert not rt.image.read("HMI1.Fault")
    rt.cycle()
    assert rt.image.read("HMI1.Fault")


def test_a_stop_the_kernel_refuses_becomes_a_hard_disable(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    """The limits keep every group stop a plan the kernel takes (a ramp of at most
    MAX_DURATION); should one still be refused, the watchdog must stop the group anyway:
    the drives go off at once (Hard Disable), one error line says why, the scan goes on."""
    rt = runtime()
    ax = rt.ctl.axis(1)
    jogging(rt)
    group_stop = rt.ctl.group_stop

    def refusing(ref: int | str, forced: object = None, owner: object = None) -> object:
        if forced != ProgrammedStopMode.HARD_DISABLE:
            raise MotionError(ErrorCode.PROFILE_FAILED, "the profile would last too long")
        return group_stop(ref, forced, owner)  # type: ignore[arg-type]

    monkeypatch.setattr(rt.ctl, "group_stop", refusing)
    beat(rt, 1)
    rt.cycle(T_CYCLES + 1)
    assert rt.image.read("HMI1.State") == WatchdogState.STOPPING
    assert rt.image.read("HMI1.Trips") == 1
    assert ax.state == AxisState.AXIS_READY and not ax.drive_enabled
    assert "HMI1" in caplog.text and "Hard Disable instead" in caplog.text
    tick = rt.ctl.tick
    rt.cycle(5)
    assert rt.ctl.tick == tick + 5  # the scan goes on
