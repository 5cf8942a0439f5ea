"""Redefining an axis's position: a shift of its coordinates by ``d``, with no motion.

MRP, MC_SetPosition and the home event of MAH and MC_Home all come down to
:func:`shift_coordinates`. The manuals' rule: "the process of redefining the current axis
position has no affect on motion in progress ... axis position can be redefined
on-the-fly without disturbing axis motion" (Logix MRP, MOTION-RM002); "this function block
does not affect the trajectory of already commanded movements" (CODESYS SM3_Basic
MC_SetPosition). So everything the axis holds moves by ``d`` together:

- its command and actual positions (continuous and quantised) and the drive's last
  command, so the following error is kept ("preserve any position error which exists");
- its ``base`` and ``position_offset`` (the sensors of :mod:`.sensors` stay where they
  are on the machine);
- the absolute positions of its own processes (the landing point of an absolute move,
  MC_GearInPos's slave sync position, a homing sequence's target): a move in progress
  ends on the same spot of the machine, which now reads its old target plus ``d``;
- what every process that follows the axis holds of its position (gear locks,
  MC_GearInPos's master sync and start positions, a master-driven profile's last master
  reading): a geared slave does not move when its master is redefined.

The axes concerned leave the fast lanes first (their lanes copied these values) and
rejoin after their next composition.
"""

from __future__ import annotations

from .axis import Axis
from .motion import Motion


def shift_coordinates(
    motion: Motion, ax: Axis, d: float, actual: float | None = None, command: float | None = None
) -> None:
    """Move ``ax``'s coordinates by ``d``. ``actual`` or ``command``, when given, is the
    exact value that reading takes (the redefined one: old + ``d`` up to rounding)."""
    motion.settle(ax)
    followers = [
        (other, p)
        for other in motion.axes
        if other is not ax
        for p in other.processes
        if p.active and ax.number in p.masters
    ]
    for other in {id(o): o for o, _ in followers}.values():
        motion.settle(other)
    s = motion.s
    i = ax.index
    for array in (s.cmd_pos, s.drv_cmd, s.act_x, s.act_pos):
        array[i] += d
    if actual is not None:
        s.act_pos[i] = actual
    if command is not None:
        s.cmd_pos[i] = command
    ax.position_offset += d
    if ax.processes:
        ax.base += d
        for p in ax.processes:
            p.shifted(d)
    else:
        # at rest the command is the base (what composition leaves): keep them equal
        ax.base = float(s.cmd_pos[i])
    for _, p in followers:
        p.master_shifted(i, d)
