"""The line example (examples/cosim/): two controller FMUs and a conveyor FMU in lockstep
under libcosim; the plant's registration sensor triggers the cutter's phase correction.
Its FMUs pass ``fmpy validate`` (the controllers as FMI 2.0 and 3.0)."""

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


@pytest.mark.slow
def test_the_sensor_closes_the_loop(line_fmus: dict[str, Path]) -> None:
    need("libcosimpy")
    line, conveyor = load("line"), load("conveyor")
    trace = line.run(line_fmus, seconds=3.0)
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
def test_without_the_sensor_the_phase_never_moves(line_fmus: dict[str, Path]) -> None:
    need("libcosimpy")
    trace = load("line").run(line_fmus, seconds=1.2, connect=False)
    assert trace["conveyor.products"][-1] >= 2
    assert not any(trace["cutter.Phase.IP"])
    assert max(abs(p) for p in phase(trace)) < 1e-3
