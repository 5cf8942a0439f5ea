"""What the cam instructions of both dialects share: the profile operand, the Logix
Execution Schedule, and the Pending hand-over (:mod:`motion_server.kernel.cams`)."""

from __future__ import annotations

from collections.abc import Callable
from enum import IntEnum

from ..kernel import Axis, Controller, ErrorCode, MotionError, ProcessKind
from ..kernel.cam_profile import CamProfile
from ..kernel.cams import MAX_SCALING, CamProcess, active_cam
from ..kernel.enums import AbortReason
from ..kernel.processes import Process
from .base import Instruction


class ExecutionSchedule(IntEnum):
    """Logix Execution Schedule (MAPC; MATC takes Immediate and Pending only)."""

    IMMEDIATE = 0
    PENDING = 1
    FORWARD_ONLY = 2
    REVERSE_ONLY = 3
    BIDIRECTIONAL = 4


def scaling(inst: Instruction, name: str) -> float:
    """A scaling operand (MAPC, MATC, MC_CamIn): finite, non-zero, within +-2^31 (ERR /
    ErrorID 13 naming it)."""
    v = float(inst.op[name])
    if not (v != 0.0 and abs(v) <= MAX_SCALING):
        raise inst.out_of_range(name, f"{name} {v:g} must be non-zero and within +-2^31")
    return v


def calculated_profile(ctl: Controller, number: int) -> CamProfile:
    """The calculated profile ``number`` (ERR 30 being calculated, 32 not calculated)."""
    slot = ctl.cams.slot(number)
    if slot.status == 1:
        raise MotionError(
            ErrorCode.CAM_PROFILE_BEING_CALCULATED, f"cam profile {number} is being calculated"
        )
    return ctl.cams.use(number)


def take_preloaded(slave: Axis, kind: ProcessKind) -> CamProcess | None:
    """The cam of ``kind`` preloaded on ``slave`` (Pending while no cam ran), taken off
    the axis: it follows the cam that starts now."""
    for p in slave.preloaded_cams:
        if p.active and p.kind == kind and isinstance(p, CamProcess):
            slave.preloaded_cams = [q for q in slave.preloaded_cams if q is not p]
            return p
    return None


def queue_pending(ctl: Controller, slave: Axis, proc: CamProcess) -> None:
    """Pending: ``proc`` takes over when the slave's current cam of its kind completes or
    passes the end of its profile; with no cam of its kind running it is preloaded and
    follows the next one. A cam already pending in its place is superseded."""
    ctl.settle(slave)  # out of the fast lanes: a cam with a successor steps in Python
    current = active_cam(slave, proc.kind)
    if current is not None:
        old = current.successor
        if old is not None and old.active:
            old.abort(AbortReason.SUPERSEDED)
        current.successor = proc
    else:
        for p in slave.preloaded_cams:
            if p.kind == proc.kind and p.active:
                p.abort(AbortReason.SUPERSEDED)
        slave.preloaded_cams = [p for p in slave.preloaded_cams if p.active] + [proc]
    slave.motion_changed()


def start_cam(
    ctl: Controller, slave: Axis, build: Callable[[], CamProcess], pending: bool
) -> CamProcess:
    """Start the cam ``build`` makes on ``slave``, superimposed on its other motion; a
    Pending one is queued behind the running cam of its kind (or preloaded) instead, and
    a cam preloaded on the axis follows the one that starts now."""
    if pending:
        proc = build()
        queue_pending(ctl, slave, proc)
        return proc

    def make(v: float, a: float) -> Process:
        p = build()
        p.successor = take_preloaded(slave, p.kind)
        return p

    started = ctl.start(slave, make, replace=())
    assert isinstance(started, CamProcess)
    return started
