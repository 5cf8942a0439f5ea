"""The FMU steps the very scan a served controller runs: a gear-in and a group stop give
the same positions, bit for bit, under fmpy (FMI 2.0 and 3.0), under libcosim (FMI 2.0)
and over Modbus with the manual clock."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from motion_server.testing import ServerFactory

from .conftest import need
from .scenario import CYCLES, OPERANDS, PERIOD, RECORD, TRIGGERS, fmpy_input, trace_of


def fmpy_trace(fmu: Path) -> dict[str, list[Any]]:
    need("fmpy")
    from fmpy import simulate_fmu

    result = simulate_fmu(
        str(fmu),
        fmi_type="CoSimulation",
        stop_time=CYCLES * PERIOD,
        output_interval=PERIOD,
        start_values=OPERANDS,
        input=fmpy_input(),
        output=RECORD,
    )
    rows = [dict(zip(result.dtype.names, row, strict=True)) for row in result]
    # fmpy records the start (0 cycles run) then every communication point
    return trace_of(rows[1:])


async def modbus_trace(server: Any) -> dict[str, list[Any]]:
    rows: list[dict[str, Any]] = []
    triggers = dict(TRIGGERS)
    by_cycle = {c: n for c, n in triggers.items()}
    async with server.client() as mc:
        await mc.write_many(OPERANDS)
        for cycle in range(CYCLES):
            if cycle in by_cycle:
                await mc.write(by_cycle[cycle], True)
            await mc.step(1)
            rows.append(await mc.read_many(RECORD))
    return trace_of(rows)


@pytest.fixture(scope="module")
def served_trace(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Any]]:
    import asyncio

    factory = ServerFactory(lambda: tmp_path_factory.mktemp("served"))
    try:
        server = factory(None, clock="manual", opcua=False)
        return asyncio.run(modbus_trace(server))
    finally:
        factory.close()


def test_the_scenario_moves(served_trace: dict[str, list[Any]]) -> None:
    """The reference run does what the scenario says (else equality proves little): the
    slave follows at half the master's motion, then the group stop ends all motion."""
    assert served_trace["Clock.Cycle"] == list(range(1, CYCLES + 1))
    assert any(served_trace["MAG_1.IP"])
    assert served_trace["MGS_1.PC"][-1]
    master = served_trace["Axis1.CommandPosition"]
    slave = served_trace["Axis2.CommandPosition"]
    assert master[119] > 10.0  # 100 mm/s for most of 0.24 s
    # geared at 0.5 on the command position, no clutch: the slave moves half as far
    assert slave[119] - slave[40] == pytest.approx((master[119] - master[40]) * 0.5, abs=1e-9)
    assert served_trace["Axis1.CommandPosition"][-1] == served_trace["Axis1.CommandPosition"][-2]


@pytest.mark.parametrize("version", [2, 3])
def test_fmpy_equals_modbus(
    version: int,
    demo_fmu2: Path,
    demo_fmu3: Path,
    served_trace: dict[str, list[Any]],
) -> None:
    fmu = demo_fmu2 if version == 2 else demo_fmu3
    trace = fmpy_trace(fmu)
    for name in RECORD:
        assert [float(v) for v in trace[name]] == [float(v) for v in served_trace[name]], name


def libcosim_trace(fmu: Path) -> dict[str, list[Any]]:
    need("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimManipulator import CosimManipulator
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    execution = CosimExecution.from_step_size(step_size=round(PERIOD * 1e9))
    slave = execution.add_local_slave(CosimLocalSlave(fmu_path=str(fmu), instance_name="ctl"))
    variables = execution.slave_variables(slave)
    refs = {v.name.decode(): v.reference for v in variables}
    kinds = {v.name.decode(): v.type for v in variables}
    for name, value in OPERANDS.items():
        if isinstance(value, bool):
            execution.boolean_initial_value(slave, refs[name], value)
        elif isinstance(value, float):
            execution.real_initial_value(slave, refs[name], value)
        else:
            execution.integer_initial_value(slave, refs[name], value)
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    manipulator = CosimManipulator.create_override()
    execution.add_manipulator(manipulator)
    by_cycle = dict(TRIGGERS)
    rows: list[dict[str, Any]] = []
    for cycle in range(CYCLES):
        if cycle in by_cycle:
            manipulator.slave_boolean_values(slave, [refs[by_cycle[cycle]]], [True])
        execution.step()
        row: dict[str, Any] = {}
        for name in RECORD:
            kind = int(kinds[name])
            if kind == 0:
                row[name] = observer.last_real_values(slave, [refs[name]])[0]
            elif kind == 1:
                row[name] = observer.last_integer_values(slave, [refs[name]])[0]
            else:
                row[name] = observer.last_boolean_values(slave, [refs[name]])[0]
        rows.append(row)
    return trace_of(rows)


def test_libcosim_equals_modbus(demo_fmu2: Path, served_trace: dict[str, list[Any]]) -> None:
    trace = libcosim_trace(demo_fmu2)
    for name in RECORD:
        assert [float(v) for v in trace[name]] == [float(v) for v in served_trace[name]], name
