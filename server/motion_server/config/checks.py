"""Checks the site-map schema shares: operand values, duplicates, numbers, periods.

Each returns problems as (field location, message) pairs; the loader turns a location
into file, line and field.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..instructions.schema import Operand, TagType

#: a problem of a site map: where (a field path as pydantic reports it) and what
Problem = tuple[tuple[int | str, ...], str]


def operand_problem(op: Operand, value: Any) -> str | None:
    """Why ``value`` cannot be the initial value of operand ``op`` (None: it can): a
    value a client could write to the operand's tag, and finite. Whether it is in the
    operand's range is judged at execution, as for a client's write."""
    kind = op.type.value
    if op.type == TagType.BOOL:
        ok = isinstance(value, int | float) and value in (0, 1)
        return None if ok else f"{value!r} is not a BOOL (true or false)"
    if isinstance(value, bool) or not isinstance(value, int | float):
        return f"{value!r} is not a number ({kind})"
    if isinstance(value, float) and not math.isfinite(value):
        return f"{value} is not finite"
    lo, hi = op.type.bounds
    if op.type.is_float:
        return None if lo <= value <= hi else f"{value} is outside the {kind} range"
    if isinstance(value, float) and not value.is_integer():
        return f"{value} is not an integer ({kind})"
    if not lo <= value <= hi:
        return f"{value} is outside the {kind} range {lo:.0f}..{hi:.0f}"
    return None


def duplicates(values: list[Any], where: tuple[str, ...], field: str) -> list[Problem]:
    seen: set[Any] = set()
    out: list[Problem] = []
    for i, v in enumerate(values):
        if v is None:
            continue
        if v in seen:
            out.append(((*where, i, field), f"duplicate {field} {v!r}"))
        seen.add(v)
    return out


def number_clashes(
    names: Sequence[str], explicit: Sequence[int | None], key: str, what: str
) -> list[Problem]:
    """Numbers given twice, explicitly or by place in the list (an unnumbered entry takes
    its 1-based place)."""
    first: dict[int, int] = {}
    out: list[Problem] = []
    for i, given in enumerate(explicit):
        number = given or i + 1
        j = first.setdefault(number, i)
        if j == i:
            continue
        # blame the entry that names the number, else the later one
        at, by = (i, j) if given is not None or explicit[j] is None else (j, i)
        how = "" if explicit[by] is not None else " (numbered by its place in the list)"
        out.append(
            ((key, at, "number"), f"{what} number {number} is taken by {what} {names[by]!r}{how}")
        )
    return out


def period_problems(periods_ms: Sequence[float]) -> list[Problem]:
    """Every group's period (``groups.<i>.coarse_update_period_ms``) must be a whole
    multiple of the fastest one (the base tick), as the kernel requires."""
    fastest = min(periods_ms) if periods_ms else 0.0
    out: list[Problem] = []
    for gi, period in enumerate(periods_ms):
        ratio = period / fastest
        if abs(round(ratio) - ratio) * fastest > 1e-6:
            out.append(
                (
                    ("groups", gi, "coarse_update_period_ms"),
                    f"{period} ms is not a multiple of the fastest group period {fastest} ms",
                )
            )
    return out
