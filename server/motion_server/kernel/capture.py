"""What a snapshot needs to capture the kernel's state whole: array views and closures.

Array views.
The kernel shares memory on purpose: the rows of :class:`~.state.AxisArrays.kinematics`
are views, the scalar paths write through memoryviews of them, status arrays are handed
out as read-only views. A plain pickle copies every view as an array of its own, and the
copy would no longer share what the original shared. :func:`reduce_view` and
:func:`reduce_memoryview` pickle a view as (the array that owns the memory, where the view
lies in it), so that every view of one array is again a view of one array after a load;
:func:`rebuild_view` and :func:`rebuild_memoryview` make them again (and check that the
view lies inside its array: a hostile offset raises, it never reads outside).

Closures. The kernel and the instructions keep a few functions made on the spot: a
buffered command's ``make(v, a)`` (:class:`~.processes.Pending`), each group's composer,
a link's ``hold_active``. A function is pickled by name only when it lives at module
level; :func:`reduce_function` pickles a nested one as (its module, its qualified name,
its first line, its cells) and :func:`rebuild_function` finds the same code object again
among the constants of the function it is nested in and binds it to the cells, so that
processes and instruction types added later (cams, ...) are captured without code of
their own. Cells are pickled as objects (:func:`reduce_cell`): two closures that shared a
cell share it again. Only code of ``motion_server.kernel`` and
``motion_server.instructions`` is rebuilt this way.

Pure functions: the snapshot codec (:mod:`motion_server.scan.statecodec`) uses them.
"""

from __future__ import annotations

import importlib
import types
from typing import Any

import numpy as np

#: the packages whose nested functions and methods a snapshot may rebuild
PACKAGES = ("motion_server.kernel", "motion_server.instructions")

#: the memoryview formats the kernel casts arrays to (float64, bool, byte)
MEMORYVIEW_FORMATS = frozenset({"d", "?", "B"})


def owner(a: np.ndarray) -> np.ndarray | None:
    """The array that owns ``a``'s memory when ``a`` is a view of another array, else None."""
    base = a.base
    while isinstance(base, np.ndarray) and base.base is not None:
        if not isinstance(base.base, np.ndarray):
            return None
        base = base.base
    if isinstance(base, np.ndarray) and base.flags.owndata:
        return base
    return None


def _address(a: np.ndarray) -> int:
    return int(a.__array_interface__["data"][0])


def reduce_view(a: np.ndarray) -> tuple[Any, ...] | None:
    """How to pickle the view ``a`` (None: ``a`` owns its memory, pickle it as it is)."""
    root = owner(a)
    if root is None:
        return None
    offset = _address(a) - _address(root)
    spec = (offset, a.shape, a.strides, a.dtype.str, bool(a.flags.writeable))
    return rebuild_view, (root, *spec)


def rebuild_view(
    root: np.ndarray,
    offset: int,
    shape: tuple[int, ...],
    strides: tuple[int, ...],
    dtype: str,
    writeable: bool,
) -> np.ndarray:
    """The view of ``root`` that :func:`reduce_view` described (ValueError when it does not
    lie inside ``root``)."""
    if not isinstance(root, np.ndarray) or not root.flags.c_contiguous:
        raise ValueError("a view of something that is not a contiguous array")
    dt = np.dtype(dtype)
    if dt.hasobject:
        raise ValueError("a view of objects")
    if not isinstance(offset, int) or offset < 0:
        raise ValueError(f"view offset {offset!r}")
    # numpy checks that shape and strides stay inside the buffer
    v = np.ndarray(shape, dtype=dt, buffer=root, offset=offset, strides=strides)
    if not writeable:
        v.flags.writeable = False
    return v


def reduce_memoryview(m: memoryview) -> tuple[Any, ...]:
    """How to pickle a memoryview of an array cast to one of the kernel's formats."""
    a = m.obj
    if (
        not isinstance(a, np.ndarray)
        or m.format not in MEMORYVIEW_FORMATS
        or m.nbytes != a.nbytes
        or not a.flags.c_contiguous
    ):
        raise TypeError("only whole-array memoryviews of contiguous arrays are captured")
    return rebuild_memoryview, (a, m.format)


def rebuild_memoryview(a: np.ndarray, fmt: str) -> memoryview[Any]:
    """A memoryview of the whole array ``a`` in ``fmt`` (see :func:`reduce_memoryview`)."""
    if not isinstance(a, np.ndarray) or fmt not in MEMORYVIEW_FORMATS:
        raise ValueError(f"memoryview of {type(a).__name__} as {fmt!r}")
    raw = a.data.cast("B")
    if fmt == "d":
        return raw.cast("d")
    return raw.cast("?") if fmt == "?" else raw


# -- closures -------------------------------------------------------------------------------
def in_packages(module: str) -> bool:
    """``module`` is part of the kernel or of the instructions."""
    return any(module == p or module.startswith(p + ".") for p in PACKAGES)


class _Empty:
    """The contents of a cell not yet bound."""


EMPTY = _Empty()


def reduce_function(f: types.FunctionType) -> tuple[Any, ...] | None:
    """How to pickle ``f`` when it is nested (None: pickle it by name, as pickle does)."""
    if "<locals>" not in f.__qualname__ and f.__closure__ is None:
        return None
    if not in_packages(f.__module__):
        raise TypeError(f"{f.__module__}.{f.__qualname__}: a closure outside the kernel")
    code = f.__code__
    return rebuild_function, (
        f.__module__,
        f.__qualname__,
        code.co_firstlineno,
        f.__closure__ or (),
        f.__defaults__,
        f.__kwdefaults__,
    )


def _nested_code(module: str, qualname: str, line: int) -> types.CodeType:
    """The code object of the function ``qualname`` of ``module`` defined at ``line``."""
    if not in_packages(module):
        raise ValueError(f"{module}: not kernel code")
    mod = importlib.import_module(module)
    parts = qualname.split(".")
    obj: Any = mod
    i = 0
    while i < len(parts) and parts[i] != "<locals>":
        obj = getattr(obj, parts[i])
        i += 1
    if i == len(parts):  # not nested after all: a module-level function with cells
        code = obj.__code__
    else:
        code = getattr(obj, "__code__", None)
        if code is None:
            raise ValueError(f"{module}.{qualname}: no such function")
        rest = parts[i:]
        while rest:
            if rest[0] != "<locals>" or len(rest) < 2:
                raise ValueError(f"{module}.{qualname}: not a nested function")
            name = rest[1]
            last = len(rest) == 2
            found = [
                c
                for c in code.co_consts
                if isinstance(c, types.CodeType)
                and c.co_name == name
                and (not last or c.co_firstlineno == line)
            ]
            if len(found) != 1:
                raise ValueError(f"{module}.{qualname} (line {line}): no longer in the code")
            code = found[0]
            rest = rest[2:]
    if code.co_firstlineno != line:
        raise ValueError(f"{module}.{qualname} (line {line}): no longer in the code")
    return code


def rebuild_function(
    module: str,
    qualname: str,
    line: int,
    cells: tuple[Any, ...],
    defaults: tuple[Any, ...] | None,
    kwdefaults: dict[str, Any] | None,
) -> types.FunctionType:
    """The function :func:`reduce_function` described (ValueError when its code is gone)."""
    code = _nested_code(module, qualname, line)
    if len(cells) != len(code.co_freevars) or not all(isinstance(c, types.CellType) for c in cells):
        raise ValueError(f"{module}.{qualname}: {len(cells)} cells for {code.co_freevars}")
    mod = importlib.import_module(module)
    f = types.FunctionType(code, mod.__dict__, code.co_name, defaults, tuple(cells))
    f.__qualname__ = qualname
    f.__kwdefaults__ = kwdefaults
    return f


def reduce_cell(cell: types.CellType) -> tuple[Any, ...]:
    """A closure cell as an object of its own (shared cells stay shared)."""
    try:
        contents = cell.cell_contents
    except ValueError:
        contents = EMPTY
    return rebuild_cell, (contents,)


def rebuild_cell(contents: Any) -> types.CellType:
    return types.CellType() if isinstance(contents, _Empty) else types.CellType(contents)


def reduce_method(m: types.MethodType) -> tuple[Any, ...]:
    """A bound method of a kernel or instruction object: (the object, the name)."""
    func = m.__func__
    if not in_packages(getattr(func, "__module__", "")):
        raise TypeError(f"{func.__qualname__}: a method outside the kernel")
    return rebuild_method, (m.__self__, func.__name__)


def rebuild_method(obj: Any, name: str) -> types.MethodType:
    """``obj.name``, a method defined in the kernel or the instructions."""
    m = getattr(type(obj), name, None)
    if not isinstance(m, types.FunctionType) or not in_packages(m.__module__):
        raise ValueError(f"{type(obj).__name__}.{name}: not a kernel method")
    return types.MethodType(m, obj)
