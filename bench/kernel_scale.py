"""Kernel step cost for 32, 256 and 1024 axes: the steady state, the worst cases and cams.

Every case starts from N/2 virtual masters and N/2 servo slaves, every slave's drive
simulated, one group at a 1 ms coarse update period, decelerations and accelerations of
1,000 mm/s² where a case ramps. In all but ``cam`` the slaves are geared to the masters
(real ratio 0.5 on the master's command position, clutch disabled: what MAG builds):

- ``steady``: masters jogging at 100 mm/s, slaves locked (2000 steps);
- ``stop``: from ``steady``, MGS Fast Stop: every axis ramps to rest (100 steps);
- ``disable``, ``hard``, ``shutdown``: the same with MGS Fast Disable (150 steps: the
  drives go off once settled), Hard Disable and Hard Shutdown (100 steps: they coast);
- ``program``: from ``steady``, Run -> Program: the programmed stop (Fast Stop) of the
  group (100 steps);
- ``mgsd``: from ``steady``, MGSD: every axis to Axis Shutdown, the drives off at once,
  the axes coast (100 steps);
- ``again``: MGS Fast Stop of a group already stopped, with four masters jogging again
  (what an operator toggling MGS makes the controller do, as ``write_abuse.py`` does):
  the axes at rest have nothing to stop (100 steps);
- ``accel``: masters at rest, slaves locked to them; MAJ from rest to 100 mm/s on every
  master, the slaves follow (100 steps);
- ``clutch``: masters jogging at 100 mm/s; MAG with the clutch enabled on every slave: the
  slaves catch up at 1,000 mm/s² from rest, then lock (60 steps);
- ``s-curve``: ``accel`` with a jerk limit of 20,000 mm/s³: each master's ramp is a
  closed-form S-curve (``kernel/scurve.py``), stepped in the S-curve lane (before that:
  ruckig's online update per axis, in Python);
- ``cam``: masters jogging at 100 mm/s; MAPC on every slave as the instruction builds it
  (a :class:`~motion_server.kernel.cams.CamProcess`: Continuous, Immediate, on the
  master's command position) over one cubic table of 9 points over 0..360 (a dwell, a rise
  of 10 mm, a dwell), master scaling 0.1 mm per cam unit: a pass is 36 mm of master, 360
  ms, so the 2000 steps measured hold five passes and more;
- ``maj``, ``mag``: ``accel`` and ``clutch`` commanded through the instructions, one MAJ
  instance per master and one MAG instance per slave (units per s and s²), all executed
  in the same scan: the command is the scan's pass over the instructions (operands
  latched and judged, the kernel commands handed over as one batch, status written:
  ``instructions/scan_pass.py``), as a scan runs it.
- ``mapc``: ``cam`` commanded through the instruction, one MAPC instance per slave
  (Continuous, Immediate, on its master's command position, the cam table's profile in
  slot 1 as MCCP computes it), all executed in the same scan (100 steps).
- ``mc_cam_in``: ``mapc`` with MC_CamIn (the table selected periodic, master and slave
  relative, MasterScaling 0.1, on the master's set value) on every slave: its cams start
  in one ``start_position_cams`` call (100 steps).
- ``mas``: from ``steady``, MAS (stop all motion, at each axis's maximum deceleration)
  on every axis, one instance per axis, all executed in the same scan: the stops as one
  batch (``Controller.stop_many``), what an HMI stopping every axis by its own MAS makes
  the controller do (100 steps);
- ``mc_stop``: the same with MC_Stop (Deceleration 1,000 mm/s², Jerk 0) on every axis:
  its stops join the same batch (100 steps);
- ``mc_halt``: the same with MC_Halt (Deceleration 1,000 mm/s², Jerk 0, aborting): its
  halts are one batch too (``stop_many`` with ``halt``: ramps that are not Stopping,
  made as objects), 100 steps;
- ``mc_velocity``: ``maj`` with MC_MoveVelocity (Velocity 100 mm/s, Acceleration and
  Deceleration 1,000 mm/s², positive, aborting) on every master: its jogs start in one
  ``start_jogs`` call that replaces every process (100 steps).
- ``mam``: ``maj`` with MAM (incremental, 50 mm at 100 mm/s, 1,000 mm/s² up and down)
  on every master: its moves start in one ``Controller.start_moves`` call (100 steps:
  0.1 s up to speed, 5 mm covered).
- ``mc_gear_in``: ``mag`` with MC_GearIn (ratio 1/2 on the master's set value, a
  trapezoidal catch-up at 1,000 mm/s² both ways, aborting) on every slave: its gears
  start in one ``start_gears`` call that replaces every process (60 steps).
- ``rejog``: from ``steady``, MAJ at 50 mm/s on every master: each jog at speed is
  replaced by a jog from 100 mm/s (``start_jogs`` on axes already moving), 100 steps;
  ``maj_rejog`` the same through one MAJ instance per master; ``s-rejog`` with a jerk
  limit of 20,000 mm/s³ (S-curves from 100 mm/s, in the S-curve lane).
- ``s-move``: masters at rest, slaves locked to them; a move of 50 mm with a jerk limit
  of 20,000 mm/s³ on every master (``start_moves``): a jerk-limited position profile,
  planned in closed form (``kernel/scurve_position.py``, once for the equal moves) and
  stepped in the S-curve lane; by ruckig per axis in Python before (100 steps).
- ``regear``: from ``steady``, MAG with the clutch at a new ratio (1/4) on every slave:
  each gear replaced by one that catches up from the slave's 50 mm/s (100 steps).
- ``move_on_jog``: from ``steady``, a move of 50 mm on every master that replaces its
  jog (the PLCopen aborting mode, MC_MoveRelative: ``start_moves`` with
  ``replace=None``), each from 100 mm/s, 100 steps.
- ``s-move_spread``: ``s-move`` with a distance of its own on every master (10 mm plus
  0.25 mm per axis number): each move planned in closed form on its own, in Python.
- ``s-move_on_jog``: ``move_on_jog`` with a jerk limit of 20,000 mm/s³: each move
  planned in closed form from the jog's cruise (once for the equal ones) and stepped in
  the S-curve lane.
- ``s-mcd``: ``s-move`` 150 steps on (every master cruising at 100 mm/s), then MCD on
  every master lowering the move's speed to 25 mm/s: beyond the new limit, a state the
  closed form leaves to ruckig, which brakes it first (one MCD per axis, as the
  instances execute). Its plan is sampled in the S-curve lane
  (``kernel/ruckig_plan.py``); before, ruckig stepped each such move in Python (100
  steps).
- ``mam_spread``: ``mam`` with a distance of its own on every master (10 mm plus 0.25 mm
  per axis number: what absolute moves to one target from different positions give),
  whose plans are built together (``kernel/move_plan.position_plans``), 100 steps.

The commands go to the kernel directly (the processes the instructions build; through
the instructions in ``maj`` and ``mag``), and as the instructions' batch commands them:
the jogs of ``accel``, ``s-curve`` and the set-ups in one ``Controller.start_jogs`` call
(the MAJ instances executed in one scan), the gears of ``clutch`` and the set-ups in one
``Controller.start_gears`` call (MAG), the cams of ``cam`` in one
:func:`~motion_server.kernel.cam_batch.start_position_cams` call (the batch entry points'
gain over one ``Controller.start`` per axis: ``start_batch.py``, ``cam_batch.py``); the
benchmark prints, per step of ``Controller.step``, the CPU time of the stepping thread
(the cost on one core, which other processes on a shared machine do not inflate): mean,
p99 and max over the case's steps, and the CPU share of the 1 ms period (target: 256
axes under 25 % in every case); then the CPU time of the command itself
and of the cycle that executes it (the command and the first step after it), with its
share of the period (the targets of issue 25: the command cycle and the step's p99
within 25 % of the period at 256 axes, 100 % at 1024). ``--repeats R`` runs each case R
times: the steps of all runs are pooled, the command figures are medians. As the scan
process does after its start-up, the heap built by the set-up is frozen
(``gc.freeze``) before the command, so that the collector does not scan it again. Each
case runs twice in the same process, side by side: with the fast lanes (the default,
``kernel/lanes/``, group stops planned as one batch: ``kernel/stop_plan.py``) and with
every axis composed in Python and stopped one by one (``Controller(lanes=False)``, the
reference the lanes are tested against bit for bit).
After each pair it prints whether the two agree: the commanded positions at the end
(``numpy.array_equal``) and the commanded position, velocity and acceleration of every
axis after every measured step (a digest taken outside the timed part); the script exits
with status 1 when they do not. For ``cam`` it prints how many cams were in a lane (the
lanes admit a process when it starts; they take it over at the next step) after the
command, after the first measured step and after the last.

    python bench/kernel_scale.py [--sizes 32 256 1024] [--cases steady stop ... cam]
        [--repeats 1]
"""

from __future__ import annotations

import argparse
import gc
import hashlib
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

from motion_server.instructions import Instruction, MotionSystem
from motion_server.kernel import (
    AxisConfig,
    AxisType,
    Controller,
    GroupConfig,
    Limits,
    MoveProcess,
    ProcessKind,
    ProgrammedStopMode,
)
from motion_server.kernel.axis import Axis
from motion_server.kernel.cam_profile import CamProfile, SegmentType, compute_profile
from motion_server.kernel.cams import CamMode, CamProcess, LockDirection
from motion_server.kernel.gearing import GearTerm, MasterReference
from motion_server.kernel.group import OperatingMode

PERIOD = 0.001
TARGET_SHARE = 0.25
#: axes -> share of the period the command cycle and the step's p99 should stay within
CYCLE_TARGET = {256: 0.25, 1024: 1.0}
SPEED = 100.0
RATE = 1000.0
JERK = 20_000.0
#: MAG's real ratio 0.5 as it builds it: 50000 / 100000 (five decimals)
RATIO = (50_000, 100_000)


def controller(n_axes: int, lanes: bool) -> Controller:
    half = n_axes // 2
    axes = [
        AxisConfig(k + 1, f"M{k + 1}", AxisType.VIRTUAL, max_velocity=1000.0,
                   max_acceleration=RATE, max_deceleration=RATE)
        for k in range(half)
    ] + [
        AxisConfig(half + k + 1, f"S{k + 1}", AxisType.SERVO, max_velocity=1000.0,
                   max_acceleration=RATE, max_deceleration=RATE, following_error_limit=50.0)
        for k in range(half)
    ]  # fmt: skip
    group = GroupConfig(1, "G", tuple(a.number for a in axes), PERIOD)
    ctl = Controller(axes, [group], lanes=lanes)
    for ax in ctl.axes:
        ctl.servo_on(ax)
    return ctl


def jog(ctl: Controller, jerk: float = 0.0) -> None:
    """MAJ at 100 mm/s on every master (from wherever it is), in one call: the jogs of
    the MAJ instances executed in one scan, as the instructions' batch commands them."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_jogs(masters, [SPEED] * len(masters), Limits(SPEED, RATE, RATE, jerk))


def gear(ctl: Controller, clutch: bool) -> None:
    """MAG on every slave, to its master's command position."""
    half = len(ctl.axes) // 2
    slaves = ctl.axes[half:]
    terms = [GearTerm(k + 1, MasterReference.COMMAND, *RATIO) for k in range(half)]
    ctl.start_gears(slaves, terms, [RATE if clutch else None] * half)


#: the cam table: 9 points over 0..360, a dwell (0..90), a rise of 10 (90..270), a dwell
CAM_MASTERS = (0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0, 360.0)
CAM_SLAVES = (0.0, 0.0, 0.0, 2.0, 5.0, 8.0, 10.0, 10.0, 10.0)
#: master mm per cam unit: one pass of 360 units is 36 mm of master, 360 ms at 100 mm/s
CAM_MASTER_SCALING = 0.1


def cam_profile() -> CamProfile:
    """The table as MCCP computes it: every segment cubic, start and end slope 0."""
    return compute_profile(CAM_MASTERS, CAM_SLAVES, [SegmentType.CUBIC] * len(CAM_MASTERS))


def cam(ctl: Controller) -> None:
    """MAPC on every slave as the instruction builds it: Continuous, Immediate, on its
    master's command position, slave scaling 1, cam lock position 0; the cams of the scan
    started as one batch (``start_position_cams``: what ``ctl.start`` on each slave
    does)."""
    from motion_server.kernel.cam_batch import CamStart, start_position_cams

    half = len(ctl.axes) // 2
    profile = cam_profile()
    axes: list[Axis] = ctl.axes
    start_position_cams(
        ctl,
        [
            CamStart(
                axes[half + k],
                axes[k],
                profile,
                CamMode.CONTINUOUS,
                1.0,
                CAM_MASTER_SCALING,
                0.0,
                MasterReference.COMMAND,
            )
            for k in range(half)
        ],
    )


def start_cam(ctl: Controller, k: int, profile: CamProfile) -> None:
    """``cam``'s MAPC on slave ``k`` (0-based among the slaves), started on its own through
    ``Controller.start``, as a scan that executes one MAPC does: Continuous, Immediate,
    on master ``k``'s command position, slave scaling 1, cam lock position 0."""
    half = len(ctl.axes) // 2
    master = ctl.axes[k]

    def make(v: float, a: float) -> CamProcess:
        return CamProcess(
            ctl,
            profile,
            CamMode.CONTINUOUS,
            1.0,
            CAM_MASTER_SCALING,
            0.0,
            master=master.index,
            source=MasterReference.COMMAND,
            master_number=master.number,
            lock=LockDirection.IMMEDIATE,
            rollover=master.config.rollover,
        )

    ctl.start(ctl.axes[half + k], make, replace=())


def cams_in_lanes(ctl: Controller) -> tuple[int, int]:
    """(cam processes in a lane, cam processes)."""
    cams = [p for ax in ctl.axes for p in ax.processes if isinstance(p, CamProcess)]
    return sum(p.lane is not None for p in cams), len(cams)


def rejog(ctl: Controller) -> None:
    """MAJ at half the speed on every master, jogging at ``SPEED`` (``jog``)."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_jogs(masters, [SPEED / 2] * len(masters), Limits(SPEED, RATE, RATE))


def s_rejog(ctl: Controller) -> None:
    """``rejog`` with a jerk limit: S-curves from ``SPEED`` to half of it."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_jogs(masters, [SPEED / 2] * len(masters), Limits(SPEED, RATE, RATE, JERK))


def s_move(ctl: Controller) -> None:
    """A move of 50 mm with a jerk limit on every master."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_moves(masters, [50.0] * len(masters), Limits(SPEED, RATE, RATE, JERK))


def regear(ctl: Controller) -> None:
    """MAG with the clutch at the ratio 1/4 on every slave, geared at 0.5 (``gear``)."""
    half = len(ctl.axes) // 2
    terms = [GearTerm(k + 1, MasterReference.COMMAND, 25_000, 100_000) for k in range(half)]
    ctl.start_gears(ctl.axes[half:], terms, [RATE] * half)


def move_on_jog(ctl: Controller) -> None:
    """A move of 50 mm replacing every master's jog at ``SPEED`` (``jog``)."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_moves(masters, [50.0] * len(masters), Limits(SPEED, RATE, RATE), replace=None)


def s_move_spread(ctl: Controller) -> None:
    """A jerk-limited move of a distance of its own on every master."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    distances = [10.0 + 0.25 * k for k in range(len(masters))]
    ctl.start_moves(masters, distances, Limits(SPEED, RATE, RATE, JERK))


def s_move_on_jog(ctl: Controller) -> None:
    """``move_on_jog`` with a jerk limit."""
    masters = ctl.axes[: len(ctl.axes) // 2]
    ctl.start_moves(masters, [50.0] * len(masters), Limits(SPEED, RATE, RATE, JERK), replace=None)


def s_mcd(ctl: Controller) -> None:
    """MCD on every master's jerk-limited move (``s-move``, cruising at ``SPEED``): the
    speed lowered to a quarter, below the velocity the move has, so that ruckig plans it
    (braking into the new limit first), one MCD per axis as its instance executes."""
    limits = Limits(SPEED, RATE, RATE, JERK)
    for ax in ctl.axes[: len(ctl.axes) // 2]:
        for p in ax.active(ProcessKind.MOVE):
            assert isinstance(p, MoveProcess)
            p.change_dynamics(limits, SPEED / 4)


def stop(ctl: Controller) -> None:
    ctl.group_stop(1, ProgrammedStopMode.FAST_STOP)


def stop_in(mode: ProgrammedStopMode) -> Callable[[Controller], None]:
    def command(ctl: Controller) -> None:
        ctl.group_stop(1, mode)

    return command


def leave_run(ctl: Controller) -> None:
    """Run -> Program: the programmed stop (Fast Stop) of every group."""
    ctl.set_mode(OperatingMode.PROGRAM)


def instructions(
    type_name: str,
    axes: Callable[[int], range],
    operands: Callable[[int, int], dict[str, object]],
) -> tuple[Callable[[Controller], None], Callable[[Controller], None]]:
    """(set-up, command) of a case that commands through instructions: the set-up adds
    one instance of ``type_name`` per axis number k of ``axes(n_axes)``, its operands
    ``operands(n_axes, k)``, to a
    :class:`~motion_server.instructions.MotionSystem` on the controller (not timed); the
    command raises every trigger and executes them, as a scan does (operands latched and
    judged, status written, the kernel command). The steps after it are the
    controller's, as in the other cases (the instances' own update is not timed)."""

    def setup(ctl: Controller) -> None:
        system = MotionSystem(ctl)
        insts = []
        for n in axes(len(ctl.axes)):
            inst = system.add(type_name, f"{type_name}{n}", {})
            inst.inputs.update(operands(len(ctl.axes), n))
            insts.append(inst)
        SYSTEMS[id(ctl)] = insts

    def command(ctl: Controller) -> None:
        # the scan pass of MotionSystem.cycle (rising edges of one type handed to the
        # kernel in one call per kind); imported here to keep this case self-contained
        from motion_server.instructions.scan_pass import scan_pass

        insts = SYSTEMS[id(ctl)]
        for inst in insts:
            inst.inputs[inst.TRIGGER] = True
        scan_pass(insts)

    return setup, command


#: the instances of the instruction cases, by id of their controller
SYSTEMS: dict[int, list[Instruction]] = {}

#: MAJ on every master at 100 mm/s, 1000 mm/s² (the ``accel`` jog), through the instruction
MAJ_SETUP, MAJ_COMMAND = instructions(
    "MAJ",
    lambda n: range(1, n // 2 + 1),
    lambda n, k: {"Axis": k, "Speed": SPEED, "AccelRate": RATE, "DecelRate": RATE, "AccelUnits": 0,
               "DecelUnits": 0},
)  # fmt: skip
#: MAJ on every master at 50 mm/s, 1000 mm/s² (the ``rejog`` jog), through the instruction
MAJ_REJOG_SETUP, MAJ_REJOG_COMMAND = instructions(
    "MAJ",
    lambda n: range(1, n // 2 + 1),
    lambda n, k: {"Axis": k, "Speed": SPEED / 2, "AccelRate": RATE, "DecelRate": RATE,
               "AccelUnits": 0, "DecelUnits": 0},
)  # fmt: skip
#: MAG with the clutch on every slave (the ``clutch`` gear), through the instruction: real
#: ratio 0.5, command reference, clutch at 1,000 mm/s² (units per s²)
MAG_SETUP, MAG_COMMAND = instructions(
    "MAG",
    lambda n: range(n // 2 + 1, n + 1),
    lambda n, k: {"SlaveAxis": k, "MasterAxis": k - n // 2, "Ratio": 0.5, "MasterReference": 1,
               "Clutch": 0, "AccelRate": RATE, "AccelUnits": 0},
)  # fmt: skip

#: MAPC on every slave (the ``cam`` cam), through the instruction: profile slot 1,
#: Continuous, master scaling 0.1 mm per cam unit, command reference
MAPC_SETUP, MAPC_COMMAND = instructions(
    "MAPC",
    lambda n: range(n // 2 + 1, n + 1),
    lambda n, k: {"SlaveAxis": k, "MasterAxis": k - n // 2, "CamProfile": 1,
               "MasterScaling": CAM_MASTER_SCALING, "ExecutionMode": CamMode.CONTINUOUS,
               "MasterReference": MasterReference.COMMAND},
)  # fmt: skip

#: MC_CamIn on every slave (``cam``'s table as a periodic selection, master and slave
#: relative, on the master's set value, MasterScaling 0.1 mm per unit), through the block
MC_CAM_IN_SETUP, MC_CAM_IN_COMMAND = instructions(
    "MC_CamIn",
    lambda n: range(n // 2 + 1, n + 1),
    lambda n, k: {"Slave": k, "Master": k - n // 2, "CamTableID": 1,
               "MasterScaling": CAM_MASTER_SCALING, "MasterValueSource": 0},
)  # fmt: skip

#: MAS (all motion, the maximum deceleration) on every axis, through the instruction
MAS_SETUP, MAS_COMMAND = instructions(
    "MAS", lambda n: range(1, n + 1), lambda n, k: {"Axis": k, "StopType": 0}
)
#: MC_Stop (1,000 mm/s², no jerk) on every axis, through the block
MC_STOP_SETUP, MC_STOP_COMMAND = instructions(
    "MC_Stop", lambda n: range(1, n + 1), lambda n, k: {"Axis": k, "Deceleration": RATE}
)
#: MC_MoveVelocity on every master at 100 mm/s, 1000 mm/s² (the ``accel`` jog), aborting,
#: through the block
MC_VELOCITY_SETUP, MC_VELOCITY_COMMAND = instructions(
    "MC_MoveVelocity",
    lambda n: range(1, n // 2 + 1),
    lambda n, k: {"Axis": k, "Velocity": SPEED, "Acceleration": RATE, "Deceleration": RATE,
               "Direction": 1},
)  # fmt: skip
#: MAM on every master, incremental 50 mm at 100 mm/s, 1000 mm/s², through the instruction
MAM_SETUP, MAM_COMMAND = instructions(
    "MAM",
    lambda n: range(1, n // 2 + 1),
    lambda n, k: {"Axis": k, "MoveType": 1, "Position": 50.0, "Speed": SPEED, "AccelRate": RATE,
               "DecelRate": RATE, "AccelUnits": 0, "DecelUnits": 0},
)  # fmt: skip
#: MC_GearIn on every slave (the ``mag`` gear as PLCopen commands it), through the block
MC_GEAR_IN_SETUP, MC_GEAR_IN_COMMAND = instructions(
    "MC_GearIn",
    lambda n: range(n // 2 + 1, n + 1),
    lambda n, k: {"Slave": k, "Master": k - n // 2, "RatioNumerator": 1.0,
               "RatioDenominator": 2.0, "MasterValueSource": 0, "Acceleration": RATE,
               "Deceleration": RATE},
)  # fmt: skip
#: ``mam`` with a distance of its own on every master
MAM_SPREAD_SETUP, MAM_SPREAD_COMMAND = instructions(
    "MAM",
    lambda n: range(1, n // 2 + 1),
    lambda n, k: {"Axis": k, "MoveType": 1, "Position": 10.0 + 0.25 * k, "Speed": SPEED,
               "AccelRate": RATE, "DecelRate": RATE, "AccelUnits": 0, "DecelUnits": 0},
)  # fmt: skip
#: MC_Halt (1,000 mm/s², no jerk, aborting) on every axis, through the block
MC_HALT_SETUP, MC_HALT_COMMAND = instructions(
    "MC_Halt", lambda n: range(1, n + 1), lambda n, k: {"Axis": k, "Deceleration": RATE}
)


def mapc_setup(ctl: Controller) -> None:
    """Masters jogging, the cam table's profile calculated into slot 1 (what MCCP leaves:
    the bench's controller declares no cam tables), one MAPC per slave."""
    from motion_server.kernel.cam_tables import ProfileSlot

    jog(ctl)
    ctl.cams.slots[1] = ProfileSlot(1, len(CAM_MASTERS), cam_profile())
    MAPC_SETUP(ctl)


def mc_cam_in_setup(ctl: Controller) -> None:
    """Masters jogging, ``cam``'s table selected as CamTableID 1 (what MC_CamTableSelect
    leaves: periodic, master and slave relative), one MC_CamIn per slave."""
    from motion_server.kernel.cam_tables import Selection

    jog(ctl)
    ctl.cams.selections[1] = Selection(cam_profile(), 1, True, False, False)
    MC_CAM_IN_SETUP(ctl)


def geared(ctl: Controller) -> None:
    """Masters jogging, slaves geared to them (the set-up of ``steady``)."""
    jog(ctl)
    gear(ctl, False)


def stopped_then_four(ctl: Controller) -> None:
    """The set-up of ``again``: ``steady``, a Fast Stop of the group run to rest, then
    four masters jogging again."""
    geared(ctl)
    ctl.run(150)
    stop(ctl)
    ctl.run(150)  # at rest: 100 mm/s at 1,000 mm/s² is 100 ms
    ctl.start_jogs(ctl.axes[:4], [SPEED] * 4, Limits(SPEED, RATE, RATE))


#: case -> (set-up, command, steps measured after the command)
CASES: dict[str, tuple[Callable[[Controller], None], Callable[[Controller], None], int]] = {
    "steady": (lambda c: (jog(c), gear(c, False)), lambda c: None, 2000),
    "stop": (lambda c: (jog(c), gear(c, False)), stop, 100),
    "disable": (geared, stop_in(ProgrammedStopMode.FAST_DISABLE), 150),
    "hard": (geared, stop_in(ProgrammedStopMode.HARD_DISABLE), 100),
    "shutdown": (geared, stop_in(ProgrammedStopMode.HARD_SHUTDOWN), 100),
    "program": (geared, leave_run, 100),
    "again": (stopped_then_four, stop, 100),
    "mgsd": (geared, lambda c: c.group_shutdown(1), 100),
    "accel": (lambda c: gear(c, False), jog, 100),
    "clutch": (jog, lambda c: gear(c, True), 60),
    "s-curve": (lambda c: gear(c, False), lambda c: jog(c, JERK), 100),
    "cam": (jog, cam, 2000),
    "maj": (lambda c: (gear(c, False), MAJ_SETUP(c)), MAJ_COMMAND, 100),
    "mag": (lambda c: (jog(c), MAG_SETUP(c)), MAG_COMMAND, 60),
    "mapc": (mapc_setup, MAPC_COMMAND, 100),
    "mc_cam_in": (mc_cam_in_setup, MC_CAM_IN_COMMAND, 100),
    "mas": (lambda c: (geared(c), MAS_SETUP(c)), MAS_COMMAND, 100),
    "mc_stop": (lambda c: (geared(c), MC_STOP_SETUP(c)), MC_STOP_COMMAND, 100),
    "mc_halt": (lambda c: (geared(c), MC_HALT_SETUP(c)), MC_HALT_COMMAND, 100),
    "mc_velocity": (
        lambda c: (gear(c, False), MC_VELOCITY_SETUP(c)),
        MC_VELOCITY_COMMAND,
        100,
    ),
    "rejog": (lambda c: (jog(c), gear(c, False)), rejog, 100),
    "s-rejog": (lambda c: (jog(c), gear(c, False)), s_rejog, 100),
    "s-move": (lambda c: gear(c, False), s_move, 100),
    "regear": (lambda c: (jog(c), gear(c, False)), regear, 100),
    "move_on_jog": (lambda c: (jog(c), gear(c, False)), move_on_jog, 100),
    "s-move_on_jog": (lambda c: (jog(c), gear(c, False)), s_move_on_jog, 100),
    "s-move_spread": (lambda c: gear(c, False), s_move_spread, 100),
    "s-mcd": (lambda c: (gear(c, False), s_move(c)), s_mcd, 100),
    "maj_rejog": (lambda c: (jog(c), gear(c, False), MAJ_REJOG_SETUP(c)), MAJ_REJOG_COMMAND, 100),
    "mam": (lambda c: (gear(c, False), MAM_SETUP(c)), MAM_COMMAND, 100),
    "mam_spread": (lambda c: (gear(c, False), MAM_SPREAD_SETUP(c)), MAM_SPREAD_COMMAND, 100),
    "mc_gear_in": (lambda c: (jog(c), MC_GEAR_IN_SETUP(c)), MC_GEAR_IN_COMMAND, 60),
}


class Run:
    """One case at one size, lanes on or off: the CPU seconds of each step after the
    command and of the command, the controller after the run, a digest of the commanded
    position, velocity and acceleration of every axis after every step (outside the timed
    part), and for cams how many were in a lane (of how many) after the command, after the
    first step and after the last."""

    def __init__(self, case: str, n_axes: int, lanes: bool) -> None:
        setup, command, steps = CASES[case]
        ctl = controller(n_axes, lanes)
        setup(ctl)
        ctl.run(150)  # jogs at speed, gears locked
        gc.collect()
        gc.freeze()
        c0 = time.thread_time()
        command(ctl)
        self.command_cpu = time.thread_time() - c0
        self.laned_command = cams_in_lanes(ctl)
        self.cpu: list[float] = []
        trace = hashlib.blake2b()
        for _ in range(steps):
            c0 = time.thread_time()
            ctl.step()
            self.cpu.append(time.thread_time() - c0)
            if len(self.cpu) == 1:
                # the cycle that executes the command: the command and the step after it
                self.command_cycle = self.command_cpu + self.cpu[0]
            for arr in (ctl.cmd_pos, ctl.cmd_vel, ctl.cmd_acc):
                trace.update(arr.tobytes())
            if len(self.cpu) == 1:
                self.laned_first = cams_in_lanes(ctl)
        self.laned_last = cams_in_lanes(ctl)
        self.trace = trace.digest()
        self.ctl = ctl
        # (collectable again: ruckig's profiles, bound with nanobind, report objects
        # still alive when the interpreter exits)
        gc.unfreeze()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", type=int, nargs="+", default=[32, 256, 1024])
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument(
        "--repeats", type=int, default=1, help="runs of each case (medians of the command)"
    )
    args = ap.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f}")
    print(
        f"{'case':>8} {'axes':>5} {'lanes':>5} {'cpu mean us':>11} {'p99 us':>8} {'max us':>8} "
        f"{'share of 1 ms':>13} {'command us':>10} {'cmd cycle us':>12} {'share':>6}"
    )
    for case in args.cases:
        for n in args.sizes:
            runs = {}
            for lanes in (False, True):
                repeats = [Run(case, n, lanes) for _ in range(args.repeats)]
                runs[lanes] = repeats[0]
                cpu = [c for r in repeats for c in r.cpu]
                mean = statistics.fmean(cpu)
                ordered = sorted(cpu)
                p99 = ordered[int(0.99 * (len(ordered) - 1))]
                share = mean / PERIOD
                command = statistics.median(r.command_cpu for r in repeats)
                cycle = statistics.median(r.command_cycle for r in repeats)
                mark = ""
                if lanes and n in CYCLE_TARGET:
                    target = CYCLE_TARGET[n]
                    mark = f"  command cycle and p99 within {target:.0%} of 1 ms: " + (
                        "met" if max(cycle, p99) <= target * PERIOD else "MISSED"
                    )
                    if n == 256:
                        mark += "; mean " + ("met" if share <= TARGET_SHARE else "MISSED")
                print(
                    f"{case:>8} {n:>5} {'on' if lanes else 'off':>5} {mean * 1e6:>11.1f} "
                    f"{p99 * 1e6:>8.1f} {ordered[-1] * 1e6:>8.1f} {share:>12.1%} "
                    f"{command * 1e6:>10.0f} {cycle * 1e6:>12.0f} {cycle / PERIOD:>6.0%}{mark}"
                )
            ref, fast = runs[False], runs[True]
            ratio = statistics.fmean(fast.cpu) / statistics.fmean(ref.cpu)
            same = np.array_equal(fast.ctl.cmd_pos, ref.ctl.cmd_pos)
            every = fast.trace == ref.trace
            line = (
                f"{'':>14} lanes: {ratio:.2f} of the reference; cmd_pos identical at the end: "
                f"{same}, commands identical after every step: {every}"
            )
            if fast.laned_last[1]:
                (cmd, total), (first, _) = fast.laned_command, fast.laned_first
                line += (
                    f"; cams in lanes {cmd}/{total} after the command, {first} after the first "
                    f"step, {fast.laned_last[0]} at the end"
                )
            print(line)
            if not (same and every):
                raise SystemExit(f"{case} {n}: lanes and reference differ")
    print(f"load average {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
