"""MC_Home: the homing sequence of PLCopen (Part 1), with the homing modes of TwinCAT's
MC_HomingMode (Tc2_MC2 / Tc3_DriveMotionControl numbering).

``Position`` is "the absolute position when the reference signal is detected" (PLCopen,
CODESYS SM3_Basic): the value the axis reads at the home event. ``HomingMode``:

- 0 ``DEFAULT``: the axis's configured homing (site map: ``home_mode``,
  ``home_sequence``, ``home_direction``, speeds; as MAH runs it) with Position as the
  value at the home event; an active sequence ends at Position + ``home_offset``;
- 1 ``ABS_SWITCH``: active homing to the home switch in the configured direction;
- 3 ``REF_PULSE``: active homing to the encoder marker in the configured direction;
  both end "with standstill" where the axis comes to rest after the event (no return
  move; "the standstill position deviates by the braking distance, nevertheless the
  calibration is exact", TwinCAT);
- 4 ``DIRECT``: the actual position becomes Position at once, no motion;
- 7 ``FORCE_CALIBRATION`` / 8 ``RESET_CALIBRATION``: set or clear Homed, nothing moves.

The modes TwinCAT numbers 2 (limit switch), 5 (absolute encoder) and 6 (block) are not
simulated (ErrorID 13). Motion modes start from StandStill, as the PLCopen state diagram
has it: power on (ErrorID 5), at rest (22), not stopping (78). The axis is in the PLCopen
state Homing while the sequence runs; Done at rest at its end (a passive DEFAULT homing:
at its home event, Active staying FALSE as nothing is commanded); CommandAborted when
another command or a stop ends it; Error with ErrorID 13 for a sequence the axis cannot
run (a sensor it lacks, speeds it has not configured).
"""

from __future__ import annotations

from dataclasses import replace
from enum import IntEnum

from ...kernel import ErrorCode, MotionError, ProcessState
from ...kernel.enums import HomeMode, HomeSequence
from ...kernel.homing import HomeFinish, HomeHandle, HomeProcess, configured
from ..base import BlockEvent, PLCopenBlock
from ..operands import AXIS
from ..registry import register
from ..schema import Operand, Quantity, TagType


class MCHomingMode(IntEnum):
    DEFAULT = 0
    ABS_SWITCH = 1
    REF_PULSE = 3
    DIRECT = 4
    FORCE_CALIBRATION = 7
    RESET_CALIBRATION = 8


@register
class MC_Home(PLCopenBlock):
    TYPE = "MC_Home"
    DESCRIPTION = "Homing: the axis reads Position at the reference signal"
    OPERANDS = (
        AXIS,
        Operand(
            "Position",
            TagType.LREAL,
            0.0,
            quantity=Quantity.POSITION,
            description="absolute position when the reference signal is detected",
        ),
        Operand(
            "HomingMode",
            TagType.DINT,
            0,
            enum=MCHomingMode,
            description="0 default (configured), 1 switch, 3 marker, 4 direct, "
            "7 force calibration, 8 reset calibration",
        ),
    )

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.handle: HomeHandle | None = None

    def execute(self) -> None:
        ax = self.axis()
        mode = MCHomingMode(int(self.op["HomingMode"]))
        self.handle = None
        if mode in (MCHomingMode.FORCE_CALIBRATION, MCHomingMode.RESET_CALIBRATION):
            ax.homed = mode == MCHomingMode.FORCE_CALIBRATION
            self.fire(BlockEvent.START)
            self.fire(BlockEvent.COMPLETE)
            return
        req = configured(ax, value=float(self.op["Position"]))
        if mode == MCHomingMode.DIRECT:
            req = replace(req, mode=HomeMode.PASSIVE, sequence=HomeSequence.IMMEDIATE)
        elif mode != MCHomingMode.DEFAULT:
            sequence = (
                HomeSequence.SWITCH if mode == MCHomingMode.ABS_SWITCH else HomeSequence.MARKER
            )
            req = replace(
                req,
                mode=HomeMode.ACTIVE,
                sequence=sequence,
                finish=HomeFinish.STOP,
                target=req.value,
            )
        if req.mode == HomeMode.ACTIVE and not req.immediate:
            self.ctl.require_motion(ax)
            if ax.stopping:
                raise MotionError(ErrorCode.NOT_ALLOWED_WHILE_STOPPING, f"{ax.name} is stopping")
            if any(p.active for p in ax.processes):
                raise MotionError(
                    ErrorCode.AXIS_IN_MOTION, f"{ax.name} is moving: MC_Home starts from StandStill"
                )
        self.handle = self.ctl.home(ax, req, owner=self)
        self.fire(BlockEvent.START)
        self.active = isinstance(self.handle, HomeProcess)
        if self.handle is None:
            self.fire(BlockEvent.COMPLETE)

    def poll(self) -> None:
        h = self.handle
        if h is None:
            return
        self.active = isinstance(h, HomeProcess) and h.active
        if h.state == ProcessState.ACTIVE:
            return
        if h.state == ProcessState.DONE:
            self.fire(BlockEvent.COMPLETE)
        elif h.state == ProcessState.ERROR:
            self.fail(h.error_code)
        else:
            self.fire(BlockEvent.ABORT)
        self.handle = None
