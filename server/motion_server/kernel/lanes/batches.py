"""Lane members admitted as one batch with their columns computed beforehand.

A command on many axes at once (:func:`..jog_batch.start_jogs`) knows, when it admits
its processes to a lane, every value the lane's rebuild would read of each
(``Lane._load``): it hands them over as columns (:func:`admit_rows`), which the next
rebuild takes as they are (:func:`batch_of`, from the lane's ``_batch_columns``) if the
batch is still all that joined, none evicted; otherwise the members are loaded one by
one as usual. :func:`spread` builds the columns of a batch whose members share a few
kinds of rows (the jogs to one target from rest share their plan).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..axis import Axis
from ..processes import Process
from .base import Lane


def admit_rows(lane: Lane, joining: Sequence[tuple[Process, Axis]], columns: list[Any]) -> None:
    """``lane.admit`` of each of ``joining`` in order (a time-driven lane: the followers
    keep their levels), with ``columns`` their ``FIELDS`` as arrays: kept for the next
    rebuild (:func:`batch_of`) if nothing else is joining."""
    mine = lane._joining
    alone = not mine
    for p, _ in joining:
        p.lane = lane
    mine.extend(joining)
    lane.changed = True
    lane._owner.joined = True
    lane._batch = (joining[0][0], len(joining), columns) if alone and joining else None


def spread(
    lane: Lane, base: np.ndarray, rows: Sequence[tuple[Any, ...]], which: np.ndarray | None
) -> list[np.ndarray]:
    """The ``FIELDS`` columns of n members: ``base`` the first, the others from the rows
    of their kinds (``rows[which[k]]`` for member k, the first row for all if ``which``
    is None), each value as it is (a row of a per-segment field is a tuple)."""
    n = len(base)
    columns = [base]
    dtypes = lane.DTYPES
    widths = lane.WIDTHS
    for j, f in enumerate(lane.FIELDS[1:]):
        dtype = dtypes.get(f, float)
        width = widths.get(f)
        if which is None:
            shape = (n,) if width is None else (n, width)
            columns.append(np.full(shape, rows[0][j], dtype=dtype))
        else:
            columns.append(np.array([r[j] for r in rows], dtype=dtype)[which])
    return columns


def batch_of(lane: Lane, joining: list[tuple[Process, Axis]]) -> list[np.ndarray] | None:
    """The columns :func:`admit_rows` kept, if ``joining`` (all that joined since the
    last rebuild, none evicted) is that batch and nothing else."""
    batch = lane._batch
    if batch is None or not joining or joining[0][0] is not batch[0]:
        return None
    if len(joining) != batch[1]:
        return None
    return list(batch[2])
