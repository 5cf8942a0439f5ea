"""The controller's state as bytes and back: pickle (protocol 5), restricted on the way in.

:func:`dumps` pickles a :class:`~motion_server.instructions.MotionSystem` (the kernel and
the instruction instances, whatever their types) with the reducers of
:mod:`motion_server.kernel.capture`: views stay views of the array they share, nested
functions and their cells are captured by reference to their code, ruckig's objects by
their inputs (``__getstate__`` where they live).

:func:`loads` reads it back with an unpickler that admits, by name, only what such a state
holds: classes of ``motion_server.kernel`` and ``motion_server.instructions``, the
rebuilders of :mod:`~motion_server.kernel.capture`, numpy's array and dtype
reconstructors, and a short list of builtin and standard-library types. Anything else is
refused (:class:`CodecError`) before it is imported. Pickle runs the constructors it names,
so a file is only loaded after its HMAC with the installation's key checked out
(:mod:`.snapshots`): the list is a second line, not the first.
"""

from __future__ import annotations

import importlib
import io
import pickle
import types
from typing import Any

import numpy as np

from ..kernel import capture

PROTOCOL = 5


class CodecError(ValueError):
    """A state that cannot be captured or read back (the message is one line)."""


class _Pickler(pickle.Pickler):
    def reducer_override(self, obj: Any) -> Any:
        t = type(obj)
        if t is np.ndarray:
            r = capture.reduce_view(obj)
            return NotImplemented if r is None else r
        if t is memoryview:
            return capture.reduce_memoryview(obj)
        if t is types.FunctionType:
            r = capture.reduce_function(obj)
            return NotImplemented if r is None else r
        if t is types.CellType:
            return capture.reduce_cell(obj)
        if t is types.MethodType:
            return capture.reduce_method(obj)
        return NotImplemented


def dumps(state: Any) -> bytes:
    """``state`` pickled (CodecError naming what could not be captured)."""
    f = io.BytesIO()
    try:
        _Pickler(f, protocol=PROTOCOL).dump(state)
    except (TypeError, pickle.PicklingError, AttributeError, ValueError) as exc:
        raise CodecError(f"the controller state cannot be captured: {exc}") from None
    except RecursionError:
        raise CodecError("the controller state cannot be captured: nested too deep") from None
    return f.getvalue()


#: standard-library names a state holds (enum members pickle as their class; sets,
#: deques and the like as themselves)
_ALLOWED = {
    ("builtins", "set"),
    ("builtins", "frozenset"),
    ("builtins", "slice"),
    ("builtins", "complex"),
    ("builtins", "range"),
    ("builtins", "bytearray"),
    ("collections", "deque"),
    ("collections", "OrderedDict"),
    ("collections", "defaultdict"),
    ("functools", "partial"),
    ("copyreg", "_reconstructor"),
    ("builtins", "object"),
    ("motion_server.scan.snapshots", "State"),
    ("numpy", "dtype"),
    ("numpy", "ndarray"),
    ("numpy.core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"),
    ("numpy._core.multiarray", "_reconstruct"),
    ("numpy._core.multiarray", "scalar"),
    ("numpy.core.numeric", "_frombuffer"),
    ("numpy._core.numeric", "_frombuffer"),
}
#: modules beyond the kernel's whose classes a state holds (the watchdogs: a group stop
#: they started names them as its owner)
_MODULES = {"motion_server.safety.watchdog"}
#: the rebuilders of kernel.capture
_REBUILDERS = {
    "rebuild_view",
    "rebuild_memoryview",
    "rebuild_function",
    "rebuild_cell",
    "rebuild_method",
}


def _admitted(module: str, name: str) -> Any:
    """The global ``module.name`` when a state may hold it, else CodecError."""
    if (module, name) in _ALLOWED:
        return getattr(importlib.import_module(module), name)
    if module == "numpy.dtypes" and name.endswith("DType"):
        return getattr(importlib.import_module(module), name)
    if module == capture.__name__ and name in _REBUILDERS:
        return getattr(capture, name)
    if (
        (capture.in_packages(module) or module in _MODULES)
        and "." not in name
        and not name.startswith("__")
    ):
        obj = getattr(importlib.import_module(module), name, None)
        # classes (enums, processes, instructions ...) and module-level functions that
        # ``make`` factories and the like name; never a module or another object
        if isinstance(obj, type) or (
            isinstance(obj, types.FunctionType) and obj.__module__ == module
        ):
            return obj
    raise CodecError(f"a snapshot may not hold {module}.{name}")


class _Unpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        return _admitted(module, name)


def loads(data: bytes) -> Any:
    """The state :func:`dumps` made (CodecError in one line when it is not one)."""
    try:
        return _Unpickler(io.BytesIO(data)).load()
    except CodecError:
        raise
    except RecursionError:
        raise CodecError("nested too deep") from None
    except Exception as exc:  # a corrupt stream raises anything: say it in one line
        text = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise CodecError(f"{type(exc).__name__}: {text}") from None
