"""Configuration of axes and motion groups as the kernel needs it (plain, validated values).

The site-map loader (``motion_server.config``) builds these from TOML; tests build them
directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .enums import (
    AxisType,
    FeedbackSignal,
    HomeDirection,
    HomeMode,
    HomeSequence,
    ProgrammedStopMode,
)

DEFAULT_PERIOD = 0.002
MIN_PERIOD = 0.001
MAX_PERIOD = 0.032


@dataclass(frozen=True)
class AxisConfig:
    """One axis. Distances in position units (``units``), time in seconds.

    ``conversion_constant`` is feedback counts per position unit (fraction gear ratios
    work in these counts). ``rollover`` > 0 makes the axis rotary: reported positions
    unwind into [0, rollover). ``max_jerk`` 0 means unlimited (trapezoidal profiles).
    ``encoder_resolution`` is the number of counts per unit the actual position is
    quantised to (0: the conversion constant). ``following_error_limit`` 0 disables the
    position-error fault.

    Homing (Logix axis attributes, MOTION-RM003): ``home_mode``, ``home_sequence``,
    ``home_direction``; the position the axis reads at the home event is
    ``home_position - home_offset`` and an active sequence ends at ``home_position``
    (see :mod:`.homing`). ``home_speed`` and ``home_return_speed`` in units/s;
    ``home_acceleration`` and ``home_deceleration`` 0 mean the axis maximum.
    The simulated sensors are fixed to the machine, in raw feedback coordinates (the
    positions the axis reads before any redefinition, see :mod:`.sensors`): a home
    switch engaged from ``home_switch`` over ``home_switch_width`` (0: to the end of
    positive travel; repeated every turn on a rotary axis), and an encoder marker every
    ``marker_interval`` from ``marker_offset`` (0: no marker).
    """

    number: int
    name: str
    type: AxisType = AxisType.SERVO
    units: str = "mm"
    conversion_constant: float = 1000.0
    rollover: float = 0.0
    max_velocity: float = 1000.0
    max_acceleration: float = 10000.0
    max_deceleration: float = 10000.0
    max_jerk: float = 0.0
    programmed_stop_mode: ProgrammedStopMode = ProgrammedStopMode.FAST_STOP
    coast_deceleration: float = 1000.0
    drive_bandwidth: float = 40.0
    encoder_resolution: float = 0.0
    following_error_limit: float = 0.0
    feedback_signal: FeedbackSignal = FeedbackSignal.INPUT
    signal_velocity: float = 0.0
    signal_amplitude: float = 0.0
    signal_frequency: float = 0.0
    home_mode: HomeMode = HomeMode.ACTIVE
    home_sequence: HomeSequence = HomeSequence.IMMEDIATE
    home_direction: HomeDirection = HomeDirection.BIDIRECTIONAL_FORWARD
    home_position: float = 0.0
    home_offset: float = 0.0
    home_speed: float = 0.0
    home_return_speed: float = 0.0
    home_acceleration: float = 0.0
    home_deceleration: float = 0.0
    home_switch: float | None = None
    home_switch_width: float = 0.0
    marker_interval: float = 0.0
    marker_offset: float = 0.0

    @property
    def counts_per_unit(self) -> float:
        return self.encoder_resolution or self.conversion_constant

    @property
    def rotary(self) -> bool:
        return self.rollover > 0.0


@dataclass(frozen=True)
class GroupConfig:
    """A motion group: its axes (by number) and its coarse update period."""

    number: int
    name: str
    axes: tuple[int, ...] = field(default_factory=tuple)
    coarse_update_period: float = DEFAULT_PERIOD
