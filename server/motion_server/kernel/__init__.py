"""The pure motion kernel: no asyncio, sockets, clocks or logging configuration here.

``Controller.step()`` advances one cycle; same inputs give bit-identical traces.

Imports point one way, from the leaves up: ``enums``, ``errors``, ``config``, ``limits``
-> ``trapezoid``, ``ruckig_profile`` -> ``scurve`` -> ``profiles``, ``state``,
``sensors``, ``cam_profile`` -> ``cam_tables``, ``processes`` -> ``override`` -> ``axis``
-> ``gearing``, ``gear_in_pos`` -> ``cams``, ``master_driven``, ``group`` -> ``lanes``
-> ``drive``, ``motion`` -> ``redefine`` -> ``homing``, ``power`` -> ``stop_plan``,
``mdac_links`` -> ``controller`` (a test checks that no import closes a loop).
"""

from .axis import Axis
from .cam_tables import CamStore, CamTableConfig
from .config import AxisConfig, GroupConfig
from .controller import ConfigError, Controller, StatusArrays
from .enums import (
    AbortReason,
    AfterStop,
    AxisFault,
    AxisState,
    AxisType,
    FeedbackSignal,
    HomeDirection,
    HomeMode,
    HomeSequence,
    MasterReference,
    MotionStatusBit,
    PLCopenState,
    ProcessKind,
    ProcessState,
    ProgrammedStopMode,
)
from .errors import ErrorCode, MotionError, TransitionError, error_text
from .group import GroupState, GroupStop, MotionGroup
from .override import Override
from .power import PowerEvent
from .processes import JogProcess, MoveProcess, Pending, Process, StopRamp
from .profiles import Limits, Profile

__all__ = [
    "AbortReason",
    "AfterStop",
    "Axis",
    "AxisConfig",
    "AxisFault",
    "AxisState",
    "AxisType",
    "CamStore",
    "CamTableConfig",
    "ConfigError",
    "Controller",
    "ErrorCode",
    "FeedbackSignal",
    "GroupConfig",
    "GroupState",
    "GroupStop",
    "HomeDirection",
    "HomeMode",
    "HomeSequence",
    "JogProcess",
    "Limits",
    "MasterReference",
    "MotionError",
    "MotionGroup",
    "MotionStatusBit",
    "MoveProcess",
    "Override",
    "PLCopenState",
    "Pending",
    "PowerEvent",
    "Process",
    "ProcessKind",
    "ProcessState",
    "Profile",
    "ProgrammedStopMode",
    "StatusArrays",
    "StopRamp",
    "TransitionError",
    "error_text",
]
