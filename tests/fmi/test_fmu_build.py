"""``motion-server fmu``: the FMU of the demo map passes ``fmpy validate`` (FMI 2.0 and
3.0) and names its variables after the tags; bad input is one line, never a traceback."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from motion_server import config
from motion_server.tagmap import build_tagmap, to_dict

from .conftest import need


def problems(fmu: Path) -> list[str]:
    need("fmpy")
    from fmpy.validation import validate_fmu

    return list(validate_fmu(str(fmu)))


@pytest.mark.parametrize("version", [2, 3])
def test_demo_fmu_validates(version: int, demo_fmu2: Path, demo_fmu3: Path) -> None:
    fmu = demo_fmu2 if version == 2 else demo_fmu3
    assert problems(fmu) == []


@pytest.mark.parametrize("version", [2, 3])
def test_variables_are_the_tags(version: int, demo_fmu2: Path, demo_fmu3: Path) -> None:
    need("fmpy")
    from fmpy import read_model_description

    md = read_model_description(str(demo_fmu2 if version == 2 else demo_fmu3))
    assert md.fmiVersion == f"{version}.0"
    assert md.variableNamingConvention == "structured"
    by_name = {v.name: v for v in md.modelVariables}
    tags = to_dict(build_tagmap(config.load(None, environ={})))["tags"]
    shown = [t for t in tags if not (t["name"].startswith("Clock.") and t["access"] != "read")]
    assert sorted(n for n in by_name if n != "time") == sorted(t["name"] for t in shown)
    assert by_name["MAG_1.DN"].causality == "output"
    assert by_name["MAG_1.Ratio"].causality == "input"
    assert by_name["Axis4.FeedbackInput"].causality == "input"
    assert by_name["Axis2.MaxVelocity"].causality == "parameter"
    assert float(by_name["Axis2.MaxVelocity"].start) == 1000.0  # the demo map's
    udint = "Integer" if version == 2 else "Int64"
    assert by_name["Clock.Cycle"].type == udint
    assert md.coSimulation is not None
    # a step of any size is taken: the part of a period is carried over
    assert md.coSimulation.canHandleVariableCommunicationStepSize
    assert float(md.defaultExperiment.stepSize) == 0.002  # the demo's coarse update period


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "motion_server.cli", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=120,
    )


def test_a_bad_site_map_is_named_not_a_traceback(tmp_path: Path) -> None:
    """As ``map`` and ``check`` say it: one line per problem, naming file, line, field."""
    need("pythonfmu")
    bad = tmp_path / "bad.toml"
    bad.write_text("[[axes]]\nname = 'A'\ntype = 'warp'\n")
    out = run_cli("fmu", str(bad), "-o", str(tmp_path / "x.fmu"), cwd=tmp_path)
    assert out.returncode == 1
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert lines[0].startswith("motion-server: bad.toml:")
    assert any("warp" in line for line in lines)
    assert not (tmp_path / "x.fmu").exists()


def test_the_output_must_be_an_fmu_file(tmp_path: Path) -> None:
    out = run_cli("fmu", "-o", str(tmp_path / "x.zip"), cwd=tmp_path)
    assert out.returncode == 1
    assert "must be a .fmu file" in out.stderr and "Traceback" not in out.stderr


def test_the_site_map_travels_in_the_fmu(demo_fmu2: Path) -> None:
    import zipfile

    with zipfile.ZipFile(demo_fmu2) as z:
        names = set(z.namelist())
        info = json.loads(z.read("resources/motion_fmu.json"))
    assert {"resources/site.toml", "resources/slave2.py", "modelDescription.xml"} <= names
    assert info == {"model": "demo2", "source": "<embedded demo.toml>", "serve": False}
