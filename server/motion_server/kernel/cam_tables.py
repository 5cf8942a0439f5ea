"""Cam tables and cam profiles as the controller holds them.

A site map declares cam tables by number: each holds up to ``capacity`` points (the Logix
CAM array: ``Master`` and ``Slave`` REAL, ``SegmentType`` DINT per element) that clients
write as tags, and ``Length``, the number of points MC_CamTableSelect uses. Every table
has a profile slot of the same number (the Logix CAM_PROFILE array): MCCP computes any
table's points into any slot, MC_CamTableSelect a table into its own. A slot holds a
:class:`~.cam_profile.CamProfile`, an immutable snapshot: the cams running on it keep it
when the table is edited or the slot recomputed.

The slot's ``status`` is the CAM_PROFILE ``Status`` word: 0 not calculated, 1 being
calculated, 2 calculated, n = calculated and in use by n - 2 cams (MAPC, MATC, MC_CamIn,
running or waiting on it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

from .cam_profile import CamError, CamProfile, compute_profile
from .errors import ErrorCode, MotionError

#: the most points a cam table may hold
MAX_CAM_POINTS = 1000
#: the most PLCopen selections (CamTableIDs) kept: older ones are forgotten (a cam that
#: runs on one keeps its profile)
MAX_SELECTIONS = 256


@dataclass(frozen=True)
class Selection:
    """A PLCopen MC_CamTableSelect: the profile it computed and how MC_CamIn runs it."""

    profile: CamProfile
    table: int
    periodic: bool
    master_absolute: bool
    slave_absolute: bool


@dataclass(frozen=True)
class CamTableConfig:
    """One cam table of the site map: ``points`` are its initial (master, slave,
    segment type) values, the rest of its ``capacity`` reads 0; ``length`` 0 means the
    number of initial points."""

    number: int
    name: str
    capacity: int
    points: tuple[tuple[float, float, int], ...] = ()
    length: int = 0


class ProfileUser(Protocol):
    """What a profile slot asks of a cam that runs on its profile."""

    @property
    def profile(self) -> CamProfile: ...

    @property
    def active(self) -> bool: ...


@dataclass
class CamTable:
    """The writable points of one table (plain lists: the tag image writes them)."""

    number: int
    name: str
    capacity: int
    master: list[float]
    slave: list[float]
    segment: list[int]
    length: int

    @classmethod
    def from_config(cls, cfg: CamTableConfig) -> CamTable:
        n = cfg.capacity
        master = [0.0] * n
        slave = [0.0] * n
        segment = [0] * n
        for k, (m, s, t) in enumerate(cfg.points):
            master[k], slave[k], segment[k] = float(m), float(s), int(t)
        length = cfg.length or len(cfg.points)
        return cls(cfg.number, cfg.name, n, master, slave, segment, length)


@dataclass
class ProfileSlot:
    """The CAM_PROFILE of one table number."""

    number: int
    capacity: int
    profile: CamProfile | None = None
    #: cams started on a profile of this slot (pruned when read)
    users: list[ProfileUser] = field(default_factory=list)

    @property
    def in_use(self) -> int:
        """Cams running (or waiting) on this slot's current profile."""
        prof = self.profile
        if prof is None:
            return 0
        live = [u for u in self.users if u.active]
        if len(live) != len(self.users):
            self.users = live
        return sum(1 for u in live if u.profile is prof)

    @property
    def status(self) -> int:
        if self.profile is None:
            return 0
        return 2 + self.in_use


class CamStore:
    """Every cam table and profile slot of a controller, by number."""

    def __init__(self, tables: Sequence[CamTableConfig] = ()) -> None:
        self.tables: dict[int, CamTable] = {}
        self.slots: dict[int, ProfileSlot] = {}
        for cfg in tables:
            if cfg.number in self.tables:
                raise ValueError(f"duplicate cam table number {cfg.number}")
            if not 2 <= cfg.capacity <= MAX_CAM_POINTS:
                raise ValueError(
                    f"cam table {cfg.name}: capacity {cfg.capacity} is outside "
                    f"[2, {MAX_CAM_POINTS}]"
                )
            if len(cfg.points) > cfg.capacity:
                raise ValueError(f"cam table {cfg.name}: more points than its capacity")
            self.tables[cfg.number] = CamTable.from_config(cfg)
            self.slots[cfg.number] = ProfileSlot(cfg.number, cfg.capacity)
        #: PLCopen selections by CamTableID (1, 2, ...; at most MAX_SELECTIONS kept)
        self.selections: dict[int, Selection] = {}
        self.last_id = 0

    def table(self, number: int) -> CamTable:
        t = self.tables.get(number)
        if t is None:
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"no cam table {number}")
        return t

    def slot(self, number: int) -> ProfileSlot:
        s = self.slots.get(number)
        if s is None:
            raise MotionError(ErrorCode.PARAMETER_OUT_OF_RANGE, f"no cam profile {number}")
        return s

    def calculate(
        self,
        table: int,
        first: int,
        length: int,
        start_slope: float,
        end_slope: float,
        slot: int,
        *,
        replace_in_use: bool = False,
    ) -> CamProfile:
        """MCCP: compute ``length`` points of ``table`` from index ``first`` into profile
        ``slot`` (MC_CamTableSelect: ``replace_in_use``, the running cams keep their
        snapshot). Raises MotionError: 26 a length below 2 or beyond the table, 27 a slot
        too short, 31 a slot in use (MCCP), and what :func:`compute_profile` raises."""
        t = self.table(table)
        s = self.slot(slot)
        if length < 2 or first < 0 or first + length > t.capacity:
            raise MotionError(
                ErrorCode.ILLEGAL_CAM_LENGTH,
                f"cam {t.name}: {length} points from element {first} do not fit its "
                f"{t.capacity} elements (at least 2 are needed)",
            )
        if length > s.capacity:
            raise MotionError(
                ErrorCode.ILLEGAL_CAM_PROFILE_LENGTH,
                f"cam profile {slot} holds {s.capacity} points, the cam has {length}",
            )
        if not replace_in_use and s.in_use:
            raise MotionError(
                ErrorCode.CAM_PROFILE_BEING_USED,
                f"cam profile {slot} is used by {s.in_use} running cam(s)",
            )
        stop = first + length
        try:
            prof = compute_profile(
                t.master[first:stop],
                t.slave[first:stop],
                t.segment[first:stop],
                start_slope,
                end_slope,
                source=table,
            )
        except CamError as exc:
            if exc.point >= 0:  # name the element of the table
                where = f"{t.name}[{first + exc.point}]"
                text = str(exc).replace(f"point {exc.point}", where, 1)
                raise CamError(exc.code, f"cam {text}", first + exc.point) from None
            raise
        s.profile = prof
        return prof

    def use(self, slot: int) -> CamProfile:
        """The calculated profile of ``slot`` for a cam that starts on it (ERR 32 when it
        is not calculated)."""
        s = self.slot(slot)
        if s.profile is None:
            raise MotionError(
                ErrorCode.CAM_PROFILE_NOT_CALCULATED, f"cam profile {slot} is not calculated"
            )
        return s.profile

    def register(self, slot: int, user: ProfileUser) -> None:
        """Count ``user`` in the slot's Status while it is active."""
        self.slot(slot).users.append(user)

    def select(
        self, table: int, periodic: bool, master_absolute: bool, slave_absolute: bool
    ) -> int:
        """MC_CamTableSelect: compute ``table``'s first ``Length`` points into its own
        profile slot (running cams keep the profile they started on) and return the new
        CamTableID."""
        t = self.table(table)
        prof = self.calculate(table, 0, t.length, 0.0, 0.0, table, replace_in_use=True)
        self.last_id += 1
        self.selections[self.last_id] = Selection(
            prof, table, bool(periodic), bool(master_absolute), bool(slave_absolute)
        )
        while len(self.selections) > MAX_SELECTIONS:
            del self.selections[next(iter(self.selections))]
        return self.last_id

    def selection(self, cam_table_id: int) -> Selection:
        """The selection of ``cam_table_id`` (MotionError 13 when there is none)."""
        sel = self.selections.get(cam_table_id)
        if sel is None:
            raise MotionError(
                ErrorCode.PARAMETER_OUT_OF_RANGE,
                f"no cam table selected as CamTableID {cam_table_id} (MC_CamTableSelect first)",
            )
        return sel
