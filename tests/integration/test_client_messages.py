"""What a new user reads when something is wrong (issue 24): one line of ours, with the
likely cause, and nothing from the libraries before it; a wrong enumeration name lists
the valid names, a wrong tag name suggests the nearest."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from motion_clients import ClientMap
from motion_clients.tagmap import MapError
from motion_server.tagmap import build_tagmap, to_dict
from tests.modbus_support import modbus_site

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def map_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("map") / "map.json"
    path.write_text(json.dumps(to_dict(build_tagmap(modbus_site()))), "utf-8")
    return path


def free_port() -> int:
    """A port nothing listens on (bound and released at once)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
    return port


def motion_client(*args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "server"), str(ROOT / "clients")])
    return subprocess.run(
        [sys.executable, "-m", "motion_clients.cli", *args],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
        check=False,
    )


def test_a_wrong_modbus_port_is_one_line_with_its_cause(map_file: Path) -> None:
    port = free_port()
    done = motion_client("--map", str(map_file), "--port", str(port), "read", "Clock.Cycle")
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        f"motion-client: cannot connect to Modbus TCP 127.0.0.1:{port}: connection refused: "
        f"nothing listens on port {port} (is motion-server running, with Modbus TCP on? "
        "At start it logs the address it serves)"
    ], done.stderr


def test_a_wrong_tag_name_suggests_the_nearest_before_connecting(map_file: Path) -> None:
    port = free_port()  # nothing listens: the name is checked first
    done = motion_client("--map", str(map_file), "--port", str(port), "read", "MAJ_1.Sped")
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        "motion-client: no tag 'MAJ_1.Sped' in the map of site 'modbus_test'; "
        "did you mean 'MAJ_1.Speed'?"
    ], done.stderr


def test_a_wrong_enumeration_name_lists_the_valid_names(map_file: Path) -> None:
    m = ClientMap.from_file(map_file)
    # MAJ Direction: forward 0, reverse 1 (the catalog's enumeration, as exported)
    with pytest.raises(MapError) as exc:
        m.tag("MAJ_1.Direction").coerce("SIDEWAYS")
    assert str(exc.value) == "MAJ_1.Direction: 'SIDEWAYS' is not one of its names: " + ", ".join(
        f"{k} ({v})" for k, v in m.tag("MAJ_1.Direction").enum.items()
    )
    assert "FORWARD (0)" in str(exc.value) and "REVERSE (1)" in str(exc.value)
    assert m.tag("MAJ_1.Direction").coerce("reverse") == 1


def test_owner_names_and_case_slips_get_a_suggestion(map_file: Path) -> None:
    m = ClientMap.from_file(map_file)
    with pytest.raises(MapError, match=r"did you mean 'Axis1\.ActualPosition'\?"):
        m.tag("axis1.actualposition")
    with pytest.raises(MapError, match=r"no axis, group or instance 'Axsi2'.*did you mean 'Axis2'"):
        m.expand(["Axsi2"])
    with pytest.raises(MapError) as exc:
        m.tag("Nothing.Like.This")
    assert "did you mean" not in str(exc.value)
