"""The catalog of instruction types: every module under ``logix/`` and ``plcopen/``
registers its class with :func:`register`; :func:`catalog` imports them all."""

from __future__ import annotations

import importlib
import pkgutil
from typing import TypeVar

from .base import Instruction

_REGISTRY: dict[str, type[Instruction]] = {}
_SUBPACKAGES = ("logix", "plcopen")
_loaded = False

T = TypeVar("T", bound=type[Instruction])


def register(cls: T) -> T:
    if not cls.TYPE:
        raise TypeError(f"{cls.__name__} has no TYPE")
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
