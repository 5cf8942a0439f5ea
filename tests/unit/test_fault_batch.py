"""A group faulted or fault-reset in one batch (``Controller.fault_axes``,
``Controller.fault_reset_axes``: a watchdog's latch and reset) leaves exactly what
``Controller.fault`` / ``fault_reset`` axis by axis, in the same order, leave.

Two controllers (lanes on, or both the reference ``lanes=False``) get the same random
motion on 16 axes, the same power commands (every power state occurs: Axis Ready, Servo
Control, Faulted, Shutdown), a group stop whose ramps may still be rows not made into
objects; then one faults a random list of axes (repeats allowed) in one batch, the other
axis by axis, and the same for the reset. They are compared attribute by attribute right
after (power state, the event that set it, fault bits, after-stop action, latch, base,
processes, every status array, the dirty marks, the change counters, the drive model's
switch count) and after every following cycle.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from motion_server.kernel import AxisState, Controller, JogProcess, Limits
from motion_server.kernel.enums import AxisFault
from motion_server.kernel.power import Power, PowerEvent
from motion_server.kernel.processes import Process

from .test_stop_plan import DT, MODES, N_AXES, Command, apply, assert_same, command, pair

POWER = ("on", "on", "off", "fault", "shutdown", "reset", "shutdown_reset", "homed")
MOTION = ("jog", "jog", "move", "gear", "clutch", "cam", "mas", "on", "mgs")
BITS = [int(b) for b in AxisFault]


def power(ctl: Controller, cmd: Command) -> None:
    """The power commands :func:`apply` does not know."""
    name, n, _, x = cmd
    ax = ctl.axes[n]
    if name == "fault":
        ctl.fault(ax, BITS[int(abs(x)) % len(BITS)])
    elif name == "shutdown":
        ctl.shutdown(ax)
    elif name == "reset":
        ctl.fault_reset(ax)
    elif name == "shutdown_reset":
        ctl.shutdown_reset(ax)
    elif name == "homed":  # as a homing leaves it (the Homed bit survives a fault)
        ax.homed = True


def run(ctl: Controller, cmd: Command, procs: list[Process], stops: list[Any]) -> str:
    if cmd[0] in ("fault", "shutdown", "reset", "shutdown_reset", "homed"):
        power(ctl, cmd)
        return ""
    return apply(ctl, cmd, procs, stops)


def bookkeeping(ctl: Controller) -> tuple[Any, ...]:
    """What ``assert_same`` leaves out: the power bookkeeping and the status caches."""
    s = ctl.arrays
    return (
        [(ax.power_event, ax.fault, ax.state, ax.after_stop) for ax in ctl.axes],
        s.axis_state.tolist(),
        s.fault.tolist(),
        s.after_stop.tolist(),
        s.busy.tolist(),
        s.drive_on.tolist(),
        s.state_changes,
        s.fault_changes,
        ctl.drive._version,
    )


def cached_status_current(ctl: Controller, where: str) -> None:
    """The status words of an axis not marked dirty are what its properties derive (the
    batch derives those of the axes it faults itself, unmarked); an axis whose ramp is a
    stop row not made yet is not read (reading would make it)."""
    s = ctl.arrays
    for ax in ctl.axes:
        if ax.index not in s.dirty and ax.stop_rows is None:
            got = (int(s.plcopen_state[ax.index]), int(s.motion_bits[ax.index]))
            assert got == (int(ax.plcopen_state), ax.process_bits()), f"{where}: {ax.name}"


def compare(a: Controller, b: Controller, ap: list[Process], bp: list[Process],
            as_: list[Any], bs: list[Any], where: str) -> None:  # fmt: skip
    assert bookkeeping(a) == bookkeeping(b), where
    cached_status_current(a, where)
    assert_same(a, b, ap, bp, as_, bs, where)


scans = st.lists(
    st.tuples(st.lists(command(MOTION + POWER), min_size=1, max_size=8), st.integers(0, 30)),
    min_size=1,
    max_size=4,
)
picks = st.lists(st.integers(0, N_AXES - 1), max_size=2 * N_AXES)


@settings(max_examples=120, deadline=None)
@given(
    lanes=st.booleans(),
    modes=st.lists(st.sampled_from(MODES), min_size=N_AXES, max_size=N_AXES),
    before=scans,
    same_scan=st.lists(command(MOTION + POWER), max_size=6),
    faulted=picks,
    bits=st.sampled_from(BITS),
    read_early=st.booleans(),
    reset=picks,
    shutdown_reset=st.booleans(),
    cycles=st.integers(0, 60),
)
def test_faulting_in_one_batch_equals_faulting_axis_by_axis(
    lanes: bool,
    modes: list[Any],
    before: list[tuple[list[Command], int]],
    same_scan: list[Command],
    faulted: list[int],
    bits: int,
    read_early: bool,
    reset: list[int],
    shutdown_reset: bool,
    cycles: int,
) -> None:
    # the batch and the calls axis by axis, on two controllers alike (lanes on or off)
    pa, pb = (pair(modes)[0], pair(modes)[0]) if lanes else (pair(modes)[1], pair(modes)[1])
    ap: list[Process] = []
    bp: list[Process] = []
    as_: list[Any] = []
    bs: list[Any] = []
    for i, (cmds, n) in enumerate(before):
        for cmd in cmds:
            assert run(pa, cmd, ap, as_) == run(pb, cmd, bp, bs), cmd
        pa.run(n)
        pb.run(n)
        compare(pa, pb, ap, bp, as_, bs, f"scan {i}")
    # commands of the scan that faults (a group stop's rows not materialised yet), read
    # or not before the fault
    for cmd in same_scan:
        assert run(pa, cmd, ap, as_) == run(pb, cmd, bp, bs), cmd
    if read_early:
        compare(pa, pb, ap, bp, as_, bs, "before the fault")
    pa.fault_axes([pa.axes[k] for k in faulted], bits)
    for k in faulted:
        pb.fault(pb.axes[k], bits)
    for ctl, procs in ((pa, ap), (pb, bp)):
        seen = {id(p) for p in procs}
        procs.extend(p for ax in ctl.axes for p in ax.processes if id(p) not in seen)
    compare(pa, pb, ap, bp, as_, bs, "after the fault")
    pa.step()
    pb.step()
    compare(pa, pb, ap, bp, as_, bs, "the cycle after the fault")
    if shutdown_reset:  # MASR / MGSR
        pa.shutdown_reset_axes([pa.axes[k] for k in reset])
        for k in reset:
            pb.shutdown_reset(pb.axes[k])
    else:
        pa.fault_reset_axes([pa.axes[k] for k in reset])
        for k in reset:
            pb.fault_reset(pb.axes[k])
    compare(pa, pb, ap, bp, as_, bs, "after the reset")
    for k in range(cycles):
        pa.step()
        pb.step()
        compare(pa, pb, ap, bp, as_, bs, f"cycle {k} after the reset")


def test_a_group_at_rest_is_faulted_without_a_power_event_per_axis(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The point of the batch: 15 stopped axes (a watchdog's latch) are faulted without one
    ``Power.fire`` each; an axis still moving goes through it (its processes end)."""
    ctl = pair([MODES[0]] * N_AXES)[0]
    moving = ctl.axes[3]
    ctl.start(moving, lambda v, a: JogProcess(DT, 5.0, Limits(5.0, 1e3, 1e3), v, a))
    ctl.step()
    fired: list[int] = []
    fire = Power.fire

    def counted(self: Power, ax: Any, event: PowerEvent) -> None:
        fired.append(ax.number)
        fire(self, ax, event)

    monkeypatch.setattr(Power, "fire", counted)
    switches = ctl.drive._version
    ctl.fault_axes(ctl.axes[: N_AXES - 1], AxisFault.WATCHDOG)
    assert fired == [moving.number]
    assert all(ax.state == AxisState.AXIS_FAULTED for ax in ctl.axes[: N_AXES - 1])
    assert not ctl.drive_on.any()
    assert ctl.drive._version == switches + N_AXES - 1  # every driven axis switched off
    assert not moving.processes
    ctl.fault_reset_axes(ctl.axes[: N_AXES - 1])
    assert fired == [moving.number]
    assert all(ax.state == AxisState.AXIS_READY and ax.fault == 0 for ax in ctl.axes[:-1])


def test_an_event_that_may_be_refused_is_not_batched() -> None:
    ctl = pair([MODES[0]] * N_AXES)[0]
    with pytest.raises(ValueError):
        ctl.power.fire_all(ctl.axes, PowerEvent.SERVO_ON)
    assert np.array_equal(ctl.drive_on[: N_AXES - 1], np.ones(N_AXES - 1, dtype=bool))


def states_table(ctl: Controller) -> None:
    """Axes 0-14 in every power state (by k % 4: Axis Ready, Servo Control, Faulted,
    Shutdown), Homed on k // 4 % 2, a passive homing waiting on k // 8, a jog on the
    axes in Servo Control with k % 3 == 0; the feedback-only axis 15 as it is."""
    for k, ax in enumerate(ctl.axes[: N_AXES - 1]):
        state = k % 4
        if state == 0:
            ctl.servo_off(ax)
        elif state == 2:
            ctl.fault(ax, AxisFault.PROFILE)
        elif state == 3:
            ctl.shutdown(ax)
        elif k % 3 == 0:
            ctl.start(ax, lambda v, a: JogProcess(DT, 5.0, Limits(5.0, 1e3, 1e3), v, a))
        ax.homed = k // 4 % 2 == 1
        ax.homing_armed = "a passive homing" if k // 8 else None
    ctl.step()


@pytest.mark.parametrize("lanes", [True, False])
@pytest.mark.parametrize("bits", [int(AxisFault.NONE), int(AxisFault.WATCHDOG)])
def test_every_power_state_homed_or_not_faulted_and_reset_in_one_batch(
    lanes: bool, bits: int
) -> None:
    pa, pb = (pair(MODES[:1] * N_AXES)[k] for k in ((0, 0) if lanes else (1, 1)))
    for ctl in (pa, pb):
        states_table(ctl)
    nothing: list[Any] = []
    compare(pa, pb, nothing, nothing, nothing, nothing, "the table")
    pa.fault_axes(pa.axes, bits)
    for ax in pb.axes:
        pb.fault(ax, bits)
    compare(pa, pb, nothing, nothing, nothing, nothing, "faulted")
    pa.step()
    pb.step()
    compare(pa, pb, nothing, nothing, nothing, nothing, "a cycle later")
    pa.fault_reset_axes(pa.axes)
    for ax in pb.axes:
        pb.fault_reset(ax)
    compare(pa, pb, nothing, nothing, nothing, nothing, "reset")
    for ctl in (pa, pb):
        for ax in ctl.axes[:4]:
            ctl.shutdown(ax)
    pa.group_shutdown_reset(1)  # MGSR: in one batch
    for ax in pb.axes:
        pb.shutdown_reset(ax)
    compare(pa, pb, nothing, nothing, nothing, nothing, "shut down and reset")
