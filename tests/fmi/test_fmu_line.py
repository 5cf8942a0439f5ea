"""The line example (examples/cosim/): two controller FMUs and a conveyor FMU in lockstep
under libcosim and under fmpy's SSP master; the plant's registration sensor triggers the
cutter's phase correction, and both masters give the same trace, bit for bit. Its FMUs
pass ``fmpy validate`` (the controllers as FMI 2.0 and 3.0)."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from motion_server.fmi.build import build_fmu

from .conftest import need
from .test_fmu_build import problems

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "cosim"


def load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"cosim_{name}", EXAMPLE / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("controller", ["infeed", "cutter"])
def test_the_line_controllers_validate(controller: str, version: int, tmp_path: Path) -> None:
    need("pythonfmu" if version == 2 else "pythonfmu3")
    fmu = build_fmu(EXAMPLE / f"{controller}.toml", tmp_path / f"{controller}.fmu", version)
    assert problems(fmu) == []


@pytest.fixture(scope="module")
def line_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    need("pythonfmu")
    fmus: dict[str, Path] = load("line").build(tmp_path_factory.mktemp("line"))
    return fmus


def test_the_plant_validates(line_fmus: dict[str, Path]) -> None:
    assert problems(line_fmus["conveyor"]) == []


def phase(trace: dict[str, Any]) -> list[float]:
    knife = trace["cutter.Knife.CommandPosition"]
    belt = trace["cutter.Belt.ActualPosition"]
    return [k - b for k, b in zip(knife, belt, strict=True)]


@pytest.fixture(scope="module")
def libcosim_trace(line_fmus: dict[str, Path]) -> dict[str, Any]:
    need("libcosimpy")
    trace: dict[str, Any] = load("line").run(line_fmus, seconds=3.0)
    return trace


def closes_the_loop(trace: dict[str, Any]) -> None:
    """The 3 s run's checks: the belt runs, the sensor sees the products, each needed
    correction runs, the knife's phase ends on the last product's offset."""
    conveyor = load("conveyor")
    # 250 mm/s for about 3 s: products at 100, 204, 301, 397, 502.5, 606, 698.5 mm
    belt = trace["infeed.Belt.ActualPosition"]
    assert 690.0 < belt[-1] < 750.0
    products = trace["conveyor.products"][-1]
    assert products == 7
    # the cutter's belt axis is the infeed's encoder, one step late (the master's exchange)
    assert trace["cutter.Belt.ActualPosition"][-1] == belt[-2]
    # every product's rising sensor edge starts a correction (IP) within a few cycles
    sensor, busy = trace["conveyor.sensor"], trace["cutter.Phase.IP"]
    rises = [i for i in range(1, len(sensor)) if sensor[i] and not sensor[i - 1]]
    assert len(rises) == products
    moved = [i for i in rises if any(busy[i : i + 5])]
    # a product whose offset equals the previous one's needs no move (the first: 0 mm)
    needed = [
        k for k in range(products) if conveyor.OFFSETS[k] != (conveyor.OFFSETS[k - 1] if k else 0.0)
    ]
    assert len(moved) == len(needed)
    # the knife's phase ends on the last product's offset from the first (0.001 mm counts)
    assert phase(trace)[-1] == pytest.approx(
        conveyor.OFFSETS[products - 1] - conveyor.OFFSETS[0], abs=1e-3
    )


@pytest.mark.slow
def test_the_sensor_closes_the_loop(libcosim_trace: dict[str, Any]) -> None:
    closes_the_loop(libcosim_trace)


@pytest.mark.parametrize("connect", [True, False])
def test_the_ssp_archive_wires_the_line(
    line_fmus: dict[str, Path], connect: bool, tmp_path: Path
) -> None:
    """fmpy reads the archive (schema-validated) and wires exactly the line's connections
    and the operator's triggers: no input left to fmpy's unconnected-input fallback."""
    need("fmpy")
    from fmpy.ssp.ssd import get_connections, read_ssd

    line = load("line")
    ssd = read_ssd(str(line.ssp(line_fmus, tmp_path / "line.ssp", connect)), validate=True)
    wired = {
        ((a.parent.name, a.name), (b.parent.name, b.name)) for a, b in get_connections(ssd.system)
    }
    expected = {c for c in line.CONNECTIONS if connect or c[0][0] != "conveyor"}
    expected |= {(("line", line.trigger_input(i, v)), (i, v)) for _, i, v in line.TRIGGERS}
    assert wired == expected
    sources = {c.source for c in ssd.system.elements}
    assert sources == {f"resources/{name}.fmu" for name in ("infeed", "conveyor", "cutter")}


@pytest.fixture(scope="module")
def fmpy_trace(
    line_fmus: dict[str, Path], tmp_path_factory: pytest.TempPathFactory
) -> dict[str, Any]:
    need("fmpy")
    trace: dict[str, Any] = load("line").run_fmpy(
        line_fmus, seconds=3.0, dest=tmp_path_factory.mktemp("ssp")
    )
    return trace


@pytest.mark.slow
def test_under_fmpy_master_the_sensor_closes_the_loop(fmpy_trace: dict[str, Any]) -> None:
    closes_the_loop(fmpy_trace)


@pytest.mark.slow
def test_fmpy_and_libcosim_give_the_same_trace(
    fmpy_trace: dict[str, Any], libcosim_trace: dict[str, Any]
) -> None:
    # both masters are Jacobi schemes on the same 2 ms grid: every value at every tick,
    # bit for bit (floats compared with ==)
    assert fmpy_trace.keys() == libcosim_trace.keys()
    for name, values in libcosim_trace.items():
        assert len(fmpy_trace[name]) == len(values) == 1500, name
        pairs = zip(fmpy_trace[name], values, strict=True)
        differ = [k for k, (a, b) in enumerate(pairs) if a != b]
        assert differ == [], f"{name} differs from step {differ[:1]}"


@pytest.mark.slow
def test_without_the_sensor_the_phase_never_moves(line_fmus: dict[str, Path]) -> None:
    need("libcosimpy")
    trace = load("line").run(line_fmus, seconds=1.2, connect=False)
    assert trace["conveyor.products"][-1] >= 2
    assert not any(trace["cutter.Phase.IP"])
    assert max(abs(p) for p in phase(trace)) < 1e-3


@pytest.mark.slow
def test_without_the_sensor_fmpy_master_equals_libcosim(line_fmus: dict[str, Path]) -> None:
    need("libcosimpy")
    need("fmpy")
    line = load("line")
    trace = line.run_fmpy(line_fmus, seconds=1.2, connect=False)
    assert trace["conveyor.products"][-1] >= 2
    assert not any(trace["cutter.Phase.IP"])
    assert trace == line.run(line_fmus, seconds=1.2, connect=False)
