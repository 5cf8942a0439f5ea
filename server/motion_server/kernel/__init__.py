"""The pure motion kernel: no asyncio, sockets, clocks or logging configuration here.

``Controller.step()`` advances one cycle; same inputs give bit-identical traces.
"""

from .axis import Axis
from .config import AxisConfig, GroupConfig
from .controller import ConfigError, Controller, Pending
from .enums import (
    AbortReason,
    AfterStop,
    AxisFault,
    AxisState,
    AxisType,
    FeedbackSignal,
    MotionStatusBit,
    PLCopenState,
    ProcessKind,
    ProcessState,
    ProgrammedStopMode,
)
from .errors import ErrorCode, MotionError, error_text
from .group import GroupState, GroupStop, MotionGroup
from .processes import JogProcess, MoveProcess, Process, StopRamp
from .profiles import Limits, Profile

__all__ = [
    "AbortReason",
    "AfterStop",
    "Axis",
    "AxisConfig",
    "AxisFault",
    "AxisState",
    "AxisType",
    "ConfigError",
    "Controller",
    "ErrorCode",
    "FeedbackSignal",
    "GroupConfig",
    "GroupState",
    "GroupStop",
    "JogProcess",
    "Limits",
    "MotionError",
    "MotionGroup",
    "MotionStatusBit",
    "MoveProcess",
    "PLCopenState",
    "Pending",
    "Process",
    "ProcessKind",
    "ProcessState",
    "Profile",
    "ProgrammedStopMode",
    "StopRamp",
    "error_text",
]
