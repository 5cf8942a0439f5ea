"""The controller behind the FMU, without an FMI builder: step sizes, refused values,
parameters, the variables' roles."""

from __future__ import annotations

import math
from importlib import resources

import pytest

from motion_server.fmi.engine import CoSimController, LogLevel, site_for_fmu
from motion_server.fmi.variables import Causality, Kind

PERIOD = 0.002  # the demo map's coarse update period


@pytest.fixture
def logged() -> list[tuple[str, LogLevel]]:
    return []


@pytest.fixture
def ctl(logged: list[tuple[str, LogLevel]]) -> CoSimController:
    text = resources.files("motion_server").joinpath("data", "demo.toml").read_text("utf-8")
    return CoSimController(site_for_fmu(text, "demo.toml"), lambda m, lvl: logged.append((m, lvl)))


def value(ctl: CoSimController, name: str) -> object:
    return ctl.get(ctl.by_name[name])


def test_whole_periods_run_that_many_cycles(ctl: CoSimController) -> None:
    assert ctl.do_step(10 * PERIOD)
    assert value(ctl, "Clock.Cycle") == 10
    # a step that is a whole number of periods after float arithmetic
    assert ctl.do_step(0.1 + 0.2 - 0.3 + 3 * PERIOD)
    assert value(ctl, "Clock.Cycle") == 13


def test_part_periods_are_carried_over_and_logged(
    ctl: CoSimController, logged: list[tuple[str, LogLevel]]
) -> None:
    # 1.5 periods a step: 1, 2, 1, 2 cycles (never drifting from the master's time)
    cycles = []
    for _ in range(4):
        assert ctl.do_step(1.5 * PERIOD)
        cycles.append(value(ctl, "Clock.Cycle"))
    assert cycles == [1, 3, 4, 6]
    warnings = [m for m, lvl in logged if lvl == LogLevel.WARNING]
    assert len(warnings) == 1 and "carried over" in warnings[0]
    # the later ones are logged too, at ok status
    assert sum(1 for m, lvl in logged if lvl == LogLevel.OK and "carried over" in m) == 1


@pytest.mark.parametrize("step", [-PERIOD, math.nan, math.inf])
def test_a_step_that_cannot_be_taken_is_refused(
    ctl: CoSimController, logged: list[tuple[str, LogLevel]], step: float
) -> None:
    assert not ctl.do_step(step)
    assert value(ctl, "Clock.Cycle") == 0
    assert logged and logged[-1][1] == LogLevel.ERROR


def test_a_refused_value_is_logged_and_the_others_are_written(
    ctl: CoSimController, logged: list[tuple[str, LogLevel]]
) -> None:
    ctl.set(ctl.by_name["MAJ_1.Speed"], math.nan)  # a REAL must be finite
    ctl.set(ctl.by_name["MAJ_1.Axis"], 3)
    assert ctl.do_step(PERIOD)
    errors = [m for m, lvl in logged if lvl == LogLevel.ERROR]
    assert len(errors) == 1 and errors[0].startswith("MAJ_1.Speed = nan not written")
    # the other input of the step was written: the image shows it
    slot = ctl.variables[ctl.by_name["MAJ_1.Axis"]].slot
    assert ctl.view.values()[slot] == 3
    assert value(ctl, "Clock.Cycle") == 1


def test_parameters_are_fixed_by_the_site_map(ctl: CoSimController) -> None:
    vr = ctl.by_name["Axis2.MaxVelocity"]
    assert ctl.variables[vr].causality == Causality.PARAMETER
    assert ctl.get(vr) == 1000.0  # the demo map's max_velocity of Axis2
    ctl.set(vr, 1000.0)  # the value it has: accepted
    with pytest.raises(ValueError, match="fixed by the site map"):
        ctl.set(vr, 5.0)


def test_roles_follow_the_tag_map(ctl: CoSimController) -> None:
    roles = {v.name: (v.causality, v.kind) for v in ctl.variables}
    assert roles["MAG_1.DN"] == (Causality.OUTPUT, Kind.BOOLEAN)
    assert roles["MAG_1.Ratio"] == (Causality.INPUT, Kind.REAL)
    assert roles["MAG_1.Execute"] == (Causality.INPUT, Kind.BOOLEAN)
    assert roles["Axis1.ActualPosition"] == (Causality.OUTPUT, Kind.REAL)
    assert roles["Axis2.HomeSwitch"] == (Causality.OUTPUT, Kind.BOOLEAN)
    # the plant side: a hand wheel's position and the fault inputs
    assert roles["Axis4.FeedbackInput"] == (Causality.INPUT, Kind.REAL)
    assert roles["Axis2.InjectDriveFault"] == (Causality.INPUT, Kind.BOOLEAN)
    assert roles["Clock.Period"][0] == Causality.PARAMETER
    # the master owns time: no clock control
    for name in ("Clock.Step", "Clock.StepCycles", "Clock.Mode", "Clock.SnapshotSave"):
        assert name not in roles
    assert roles["Clock.Cycle"] == (Causality.OUTPUT, Kind.INTEGER)


def test_udint_inputs_take_fmi2_negative_integers_as_unsigned(ctl: CoSimController) -> None:
    vr = ctl.by_name["MAG_1.SlaveCounts"]
    ctl.set(vr, -1)  # an FMI 2.0 Integer holding 2^32 - 1
    assert ctl.get(vr) == 2**32 - 1


def test_the_servers_warnings_reach_the_fmu_logger(
    ctl: CoSimController, logged: list[tuple[str, LogLevel]]
) -> None:
    # a subnormal REAL is accepted, and the server warns of it (the mark of a wrong word
    # order on Modbus): the master sees that warning through the FMU's logger
    ctl.set(ctl.by_name["MAJ_1.Speed"], 1e-40)
    assert ctl.do_step(PERIOD)
    warnings = [m for m, lvl in logged if lvl == LogLevel.WARNING]
    assert any("MAJ_1.Speed" in m and "subnormal" in m for m in warnings), logged
