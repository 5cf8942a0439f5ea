"""The pytest plugin as an HMI team uses it: the package installed with pip into a fresh
virtual environment outside this repository, and the example of
docs/testing-with-pytest.md (its files, as the document gives them) run with that
environment's pytest."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from motion_server.testing import MotionServer

REPO = Path(__file__).resolve().parents[2]
DOC = REPO / "docs" / "testing-with-pytest.md"

#: one more test file: the package under test is the one pip installed
INSTALLED = """\
import motion_server


def test_the_package_is_the_installed_one():
    assert "site-packages" in motion_server.__file__
"""


def example_files() -> dict[str, str]:
    """The files of the document's example: fenced blocks whose info string names one
    (```python conftest.py)."""
    text = DOC.read_text("utf-8")
    blocks = re.findall(r"^```\w+ ([\w.]+)\n(.*?)^```$", text, flags=re.M | re.S)
    return dict(blocks)


def test_the_document_gives_the_four_files_of_its_tree() -> None:
    assert sorted(example_files()) == ["conftest.py", "line1.toml", "pytest.ini", "test_panel.py"]


def _pip_source_tree(dest: Path) -> Path:
    """What a clone holds for pip: the project metadata and the two packages."""
    src = dest / "motion-server"
    src.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, src / name)
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")
    for name in ("server", "clients"):
        shutil.copytree(REPO / name, src / name, ignore=ignore)
    return src


@pytest.mark.slow
def test_an_hmi_project_uses_the_fixtures_after_pip_install(tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    src = _pip_source_tree(tmp_path)
    pip = subprocess.run(
        [str(venv / "bin" / "pip"), "install", "--quiet", f"{src}[pytest]"],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert pip.returncode == 0, pip.stderr[-3000:]
    project = tmp_path / "hmi-tests"
    project.mkdir()
    for name, text in example_files().items():
        (project / name).write_text(text)
    (project / "test_installed.py").write_text(INSTALLED)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "MOTION_SERVER_"))}
    for name in ("PYTEST_ADDOPTS", "VIRTUAL_ENV", "CI"):
        env.pop(name, None)
    run = subprocess.run(
        [str(venv / "bin" / "python"), "-m", "pytest", "-q", "-p", "no:cacheprovider"],
        cwd=project,
        env=env,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stdout[-5000:] + run.stderr[-2000:]
    # every test passed, and nothing warned (no "4 passed, 1 warning")
    assert re.search(r"^4 passed in [\d.]+s", run.stdout, flags=re.M), run.stdout


ONE_AXIS = """\
[[groups]]
name = "G"
axes = ["Only"]

[[axes]]
name = "Only"
type = "virtual"

[opcua]
enabled = false
"""

FAILING = """\
from pathlib import Path
import os
import signal


def test_the_ini_option_names_the_site_map(motion_server):
    assert motion_server.read("Diagnostics.AxisCount") == 1


def test_a_scan_that_dies_fails_the_test(motion_server):
    pid = motion_server.pid
    children = Path(f"/proc/{pid}/task/{pid}/children").read_text().split()
    for child in children:
        if b"motion_server.scan" in Path(f"/proc/{child}/cmdline").read_bytes():
            os.kill(int(child), signal.SIGKILL)
    motion_server.proc.wait(60)
"""


def test_the_plugin_reads_its_ini_option_and_reports_a_dead_server(
    pytester: pytest.Pytester,
) -> None:
    pytester.makefile(".toml", one_axis=ONE_AXIS)
    pytester.makeini("[pytest]\nmotion_site_map = one_axis.toml\n")
    pytester.makepyfile(test_plugin=FAILING)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    # the second test passed its body; the dead server fails it at teardown
    result.assert_outcomes(passed=2, errors=1)
    result.stdout.fnmatch_lines(
        [
            "*ERROR at teardown of test_a_scan_that_dies_fails_the_test*",
            "*motion-server died during the test (exit status 1)*",
        ]
    )
    result.stdout.fnmatch_lines(["*the scan process died (killed by SIGKILL)*"])


def test_a_stale_ready_file_is_not_taken_for_the_new_server(tmp_path: Path) -> None:
    """A server killed in the same directory left its ready file: the next start waits
    for its own."""
    (tmp_path / "ready.json").write_text('{"pid": 1, "modbus": {"port": 1}}')
    server = MotionServer.start(tmp_path, opcua=False)
    try:
        assert server.info["pid"] == server.pid
        assert server.modbus_port not in (0, 1)
        assert server.read("Diagnostics.Ready") is True
    finally:
        assert server.stop() == 0, server.log_tail()
