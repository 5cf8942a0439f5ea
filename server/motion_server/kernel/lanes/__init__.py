"""Fast lanes: the motion states of many axes stepped as numpy arrays.

Stepping one process object per axis in Python costs about a microsecond each; a lane
steps all processes of one kind and state with a few array operations that repeat the
objects' floating-point operations in the same order, so the results are bit-identical
(a test runs a controller with and one without lanes side by side). The lanes:

- time-driven (:mod:`.ramps`): jogs at speed; trapezoidal jogs and moves on their way
  (accelerating, cruising, decelerating, reversing); trapezoidal stop ramps (MGS, MAS,
  MC_Stop, MC_Halt and the ramp of a failed process); (:mod:`.scurve`) jerk-limited
  ramps to a velocity (jogs, speed changes, paused moves, jerk-limited stops) and
  jerk-limited moves, planned in closed form or by ruckig (its phases as segments);
- followers on one master (:mod:`.gears`): locked gears with a real or a fraction ratio,
  and gears catching up at a rate (the MAG clutch, the trapezoidal PLCopen catch-up);
  (:mod:`.cams`) locked position cams (MAPC, MC_CamIn) following both master
  directions, without a Pending successor or a ramp-in still ahead.

Jerk-limited profiles ruckig steps itself (a plan of more than eight phases, or one
whose end misses ruckig's precision: :mod:`..ruckig_plan`), jerk-limited catch-up ramps,
two-master gears,
MC_GearInPos, master-driven motion, time cams, cams waiting for a lock position or
following one master direction, axes with more than one process or a buffered command
stay in Python.

Membership:

- An axis joins a lane when its only process is in such a state and it has no buffered
  command: when the command starts it, or after the controller composed it in Python.
- It leaves when anything touches its motion: a new command, a stop, a release, an abort
  (``Controller.settle``). Leaving first writes the lane's values back into the process
  object. A change of dynamics (``ProfiledProcess.change_dynamics``: MCD, an override)
  of a member of a plan lane rewrites its row instead (``PlanLane.replan``), unless the
  new plan is the other lane's (a jerk limit set or cleared): it then leaves.
- A step in which a member changes state (a profile or ramp ends, a gear catches up, a
  fraction gear's counts outgrow int64) is the process's own: the lane moves the member
  out before it computes, and the axis is composed in Python in that step, then offered
  again. Events cost Python work; the steady arithmetic between them does not. The
  common events are ended by the lanes themselves, as arrays: a stop ramp reaching rest
  (the stop lane), a trapezoidal jog reaching its velocity (the profile lane hands it
  to the cruise lane) and a real-ratio gear catching up (the catch-up lane locks it and
  hands it to the gear lane).

The order of the steps and the levels of the followers: :mod:`.group`.
"""

from .group import GroupLanes

__all__ = ["GroupLanes"]
