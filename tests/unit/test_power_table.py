"""The power states as a table: every command event has a row in every state, the
preconditions refuse with the Logix .ERR codes (DESIGN: 5 servo off, 7 shutdown, 8 wrong
axis type, 20 axis faulted), and a missing pair raises the one TransitionError every
state table of the server shares."""

from __future__ import annotations

import pytest

import motion_server.instructions.base as instruction_base
import motion_server.safety.watchdog as watchdog
from motion_server.kernel import (
    AxisConfig,
    AxisState,
    AxisType,
    Controller,
    ErrorCode,
    GroupConfig,
    MotionError,
    PowerEvent,
    TransitionError,
)
from motion_server.kernel.power import TRANSITIONS, require

COMMANDS = [
    e for e in PowerEvent if e not in (PowerEvent.STOPPED_DISABLE, PowerEvent.STOPPED_SHUTDOWN)
]


def test_every_command_event_has_a_transition_in_every_state() -> None:
    missing = [(s, e) for s in AxisState for e in COMMANDS if (s, e) not in TRANSITIONS]
    assert missing == []


def test_one_transition_error_for_every_state_table() -> None:
    assert instruction_base.TransitionError is TransitionError
    assert watchdog.TransitionError is TransitionError


def controller() -> Controller:
    axes = [AxisConfig(1, "Axis1", AxisType.SERVO), AxisConfig(2, "Wheel", AxisType.FEEDBACK_ONLY)]
    return Controller(axes, [GroupConfig(1, "G", (1, 2), 0.002)])


@pytest.mark.parametrize(
    ("state", "code"),
    [(AxisState.AXIS_READY, 5), (AxisState.AXIS_SHUTDOWN, 7), (AxisState.AXIS_FAULTED, 20),
     (AxisState.SERVO_CONTROL, None)],
)  # fmt: skip
def test_motion_preconditions_refuse_with_the_logix_codes(
    state: AxisState, code: int | None
) -> None:
    ctl = controller()
    ax, wheel = ctl.axis(1), ctl.axis(2)
    ax.state = state
    wheel.state = state
    if code is None:
        require(ax, PowerEvent.MOTION)
    else:
        with pytest.raises(MotionError) as err:
            ctl.require_motion(ax)
        assert err.value.code == code
    with pytest.raises(MotionError) as err:
        ctl.require_motion(wheel)
    assert err.value.code == ErrorCode.WRONG_AXIS_TYPE == 8


def test_a_pair_missing_from_the_table_names_state_and_event() -> None:
    ctl = controller()
    with pytest.raises(TransitionError) as err:
        ctl.power.fire(ctl.axis(1), PowerEvent.STOPPED_DISABLE)  # only from Servo Control
    assert "AXIS_READY" in str(err.value) and "STOPPED_DISABLE" in str(err.value)
