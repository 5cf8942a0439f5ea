"""FMUs built once per session (by ``motion-server fmu``); tests that need an optional
package skip naming it."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from motion_server.fmi.build import build_fmu

EXTRA = "pip install 'motion-server[fmi]'"


def need(package: str) -> None:
    if importlib.util.find_spec(package) is None:
        pytest.skip(f"{package} is not installed ({EXTRA})")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def demo_fmu2(fmu_dir: Path) -> Path:
    need("pythonfmu")
    return build_fmu(None, fmu_dir / "demo2.fmu", 2)


@pytest.fixture(scope="session")
def demo_fmu3(fmu_dir: Path) -> Path:
    need("pythonfmu3")
    return build_fmu(None, fmu_dir / "demo3.fmu", 3)
