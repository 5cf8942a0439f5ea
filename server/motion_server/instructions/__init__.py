"""Logix and PLCopen instruction semantics on top of the kernel."""

from .base import BlockState, Dialect, Instruction, LogixInstruction, OperandError, PLCopenBlock
from .registry import catalog, instruction_type, register
from .schema import Kind, Operand, Quantity, StatusField, TagType
from .system import MotionSystem

__all__ = [
    "BlockState",
    "Dialect",
    "Instruction",
    "Kind",
    "LogixInstruction",
    "MotionSystem",
    "Operand",
    "OperandError",
    "PLCopenBlock",
    "Quantity",
    "StatusField",
    "TagType",
    "catalog",
    "instruction_type",
    "register",
]
