"""How the operating system schedules the scan and the Modbus front-end.

A controller's motion task preempts everything else, and its communication with the
devices that command it comes next. Here the scan asks for the real-time policy
(SCHED_FIFO) at :data:`SCAN_RT_PRIORITY` while its clock follows the wall clock, and the
Modbus front-end at :data:`MODBUS_RT_PRIORITY` below it: a PLC's write and its polls of DN
are then answered at once, even while an OPC UA subscriber's notifications (bulk work, left
to the ordinary policy) keep both cores busy. Either needs root or CAP_SYS_NICE (a
container: ``--cap-add SYS_NICE`` and a runtime that permits real-time scheduling);
without it the process keeps the priority it has, said once at DEBUG.

A real-time process busy beyond its overload share of a second would leave the other
processes on the machine (the other front-end, the supervisor, on one core everything)
almost no time, so it goes back to the ordinary policy, the first time with a warning:
the scan for good (it cannot keep its period then), the Modbus front-end until its load
has fallen below half that share again (a flood of requests has passed).
"""

from __future__ import annotations

import logging
import os
import time

log = logging.getLogger("motion_server.scheduling")

#: the scan's real-time priority (SCHED_FIFO, 1-99) while the clock runs in real time
SCAN_RT_PRIORITY = 10
#: the Modbus front-end's: below the scan's, so a cycle still preempts it
MODBUS_RT_PRIORITY = 5
#: seconds over which a process's load is measured
LOAD_WINDOW = 1.0


class Policy:
    """One process's scheduling: real-time while wanted and not overloaded.

    ``name`` names the process in the log; ``priority`` is its SCHED_FIFO priority;
    ``overload`` the share of a second (%) busy beyond which it leaves the real-time
    policy: for good, or with ``recover`` until its load is below half of it again;
    ``nice``, when given, the nice value asked for at once (kept under the ordinary
    policy)."""

    def __init__(
        self,
        name: str,
        priority: int,
        overload: float,
        nice: int | None = None,
        recover: bool = False,
    ) -> None:
        self.name = name
        self.priority = priority
        self.overload = overload
        self.recover = recover
        self.realtime: bool | None = None
        self.demoted = False
        self.unavailable = False  # the system does not allow it: not asked again
        self.episodes = 0  # times it left the real-time policy: the first is a warning
        self._since = 0.0
        if nice is not None:
            try:
                os.setpriority(os.PRIO_PROCESS, 0, nice)
            except OSError as exc:
                log.debug("%s priority unchanged: %s", name, exc)
            else:
                log.debug("%s priority raised (nice %d)", name, nice)

    def follow(self, wanted: bool, load: float) -> None:
        """Apply the policy: real-time when ``wanted``. ``load``: the share of the last
        :data:`LOAD_WINDOW` the process was busy (%), judged only once the current policy
        has run for two windows (the load measured before is not this policy's)."""
        if self.unavailable:
            return
        settled = time.monotonic() - self._since > 2 * LOAD_WINDOW
        if load > self.overload and self.realtime and settled and not self.demoted:
            self.demoted = True
            self.episodes += 1
            log.log(
                logging.WARNING if self.episodes == 1 else logging.DEBUG,
                "%s busy %.0f %% of the time: it leaves the real-time scheduling policy%s "
                "so that the other processes on the machine are still served",
                self.name,
                load,
                " while this lasts" if self.recover else "",
            )
        elif self.demoted and self.recover and settled and load < self.overload / 2:
            self.demoted = False
            log.debug("%s busy %.0f %% of the time: real-time again", self.name, load)
        realtime = wanted and not self.demoted
        if realtime == self.realtime:
            return
        self.realtime = realtime
        self._since = time.monotonic()
        policy, priority = (os.SCHED_FIFO, self.priority) if realtime else (os.SCHED_OTHER, 0)
        try:
            os.sched_setscheduler(0, policy, os.sched_param(priority))
        except OSError as exc:
            if realtime:
                self.unavailable = True
                self.realtime = False
                log.debug("%s keeps the ordinary scheduling policy: %s", self.name, exc)
        else:
            log.debug("%s scheduling: %s", self.name, "SCHED_FIFO" if realtime else "SCHED_OTHER")


class CpuLoad:
    """The share of each :data:`LOAD_WINDOW` this process spent on a CPU (%), for a
    process whose work is not timed piece by piece (a front-end's event loop)."""

    def __init__(self) -> None:
        self._wall = time.monotonic()
        self._cpu = time.process_time()
        self.load = 0.0

    def sample(self) -> float:
        wall, cpu = time.monotonic(), time.process_time()
        if wall - self._wall >= LOAD_WINDOW:
            self.load = 100.0 * (cpu - self._cpu) / (wall - self._wall)
            self._wall, self._cpu = wall, cpu
        return self.load
