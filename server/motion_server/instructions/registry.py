"""The catalog of instruction types: every module under ``logix/`` and ``plcopen/``
registers its class with :func:`register`; :func:`catalog` imports them all."""

from __future__ import annotations

import importlib
import pkgutil
from typing import TypeVar

from .base import Instruction

_REGISTRY: dict[str, type[Instruction]] = {}

#: Stable number of every instruction type. Append-only: the demo map's ``<TYPE>_1``
#: instances sit at a register block chosen by this number, so adding a type never moves
#: the registers of the others. A new type must get the next free number here.
TYPE_CODES: dict[str, int] = {
    "MSO": 1,
    "MSF": 2,
    "MAFR": 3,
    "MASD": 4,
    "MASR": 5,
    "MAJ": 6,
    "MAM": 7,
    "MAS": 8,
    "MCD": 9,
    "MAG": 10,
    "MGS": 11,
    "MGSD": 12,
    "MGSR": 13,
    "MDAC": 14,
    # cams (Logix): 15-18
    "MCCP": 15,
    "MCSV": 16,
    "MAPC": 17,
    "MATC": 18,
    "MC_Power": 21,
    "MC_Reset": 22,
    "MC_MoveAbsolute": 23,
    "MC_MoveRelative": 24,
    "MC_MoveVelocity": 25,
    "MC_Stop": 26,
    "MC_Halt": 27,
    "MC_GearIn": 28,
    "MC_GearOut": 29,
    "MC_GearInPos": 30,
    "MC_CombineAxes": 31,
    # cams (PLCopen): 32-34
    "MC_CamTableSelect": 32,
    "MC_CamIn": 33,
    "MC_CamOut": 34,
    "MC_MoveAdditive": 40,
    "MC_MoveSuperimposed": 41,
    "MC_SetOverride": 42,
    "MC_HaltSuperimposed": 43,
    # homing, redefined positions, status and parameter blocks: 50-69
    "MAH": 50,
    "MRP": 51,
    "MC_Home": 52,
    "MC_SetPosition": 53,
    "MC_ReadStatus": 54,
    "MC_ReadAxisError": 55,
    "MC_ReadActualPosition": 56,
    "MC_ReadActualVelocity": 57,
    "MC_ReadParameter": 58,
    "MC_WriteParameter": 59,
    "MC_ReadBoolParameter": 60,
    "MC_WriteBoolParameter": 61,
}
_SUBPACKAGES = ("logix", "plcopen")
_loaded = False

T = TypeVar("T", bound=type[Instruction])


def register(cls: T) -> T:
    if not cls.TYPE:
        raise TypeError(f"{cls.__name__} has no TYPE")
    if cls.TYPE not in TYPE_CODES:
        raise TypeError(f"instruction type {cls.TYPE} has no entry in registry.TYPE_CODES")
    if cls.TYPE in _REGISTRY and _REGISTRY[cls.TYPE] is not cls:
        raise TypeError(f"instruction type {cls.TYPE} registered twice")
    _REGISTRY[cls.TYPE] = cls
    return cls


def catalog() -> dict[str, type[Instruction]]:
    """Every instruction type, by name, in a stable order (dialect, then name)."""
    global _loaded
    if not _loaded:
        for sub in _SUBPACKAGES:
            pkg = importlib.import_module(f"{__package__}.{sub}")
            for info in pkgutil.iter_modules(pkg.__path__):
                importlib.import_module(f"{pkg.__name__}.{info.name}")
        _loaded = True
    return dict(sorted(_REGISTRY.items(), key=lambda kv: (kv[1].DIALECT.value, kv[0])))


def instruction_type(name: str) -> type[Instruction]:
    types = catalog()
    try:
        return types[name]
    except KeyError:
        raise KeyError(f"unknown instruction type {name!r}; known: {', '.join(types)}") from None


def type_code(name: str) -> int:
    """The stable number of an instruction type (see :data:`TYPE_CODES`)."""
    return TYPE_CODES[name]
