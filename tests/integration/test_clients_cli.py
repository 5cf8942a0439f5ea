"""``motion-client`` commands against a server (manual clock, ephemeral port)."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_clients.cli import main
from motion_clients.plot import is_png
from motion_clients.trace import Trace
from motion_server.tagmap import build_tagmap, to_dict
from tests.clients_support import manual_site
from tests.modbus_support import ServerThread, modbus_site


@pytest.fixture
def cli(tmp_path: Path) -> Iterator[list[str]]:
    """The leading arguments: --map <json> --port <port>."""
    site = manual_site(modbus_site())
    map_file = tmp_path / "map.json"
    map_file.write_text(json.dumps(to_dict(build_tagmap(site))), "utf-8")
    with ServerThread(site) as srv:
        yield ["--map", str(map_file), "--port", str(srv.port)]


def test_read_write_trigger_step(cli: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        main([*cli, "write", "MAJ_1.Speed=10", "MAJ_1.AccelRate=100", "MAJ_1.DecelRate=100"]) == 0
    )
    assert main([*cli, "trigger", "MSO_1", "Axis=1"]) == 0
    assert "MSO_1: DN after 1 cycle(s)" in capsys.readouterr().out
    assert main([*cli, "trigger", "MAJ_1", "Axis=1", "Direction=FORWARD"]) == 0
    assert main([*cli, "step", "99"]) == 0
    assert "cycle 101" in capsys.readouterr().out  # 1 (MSO) + 1 (MAJ) + 99
    assert main([*cli, "read", "Axis1.CommandPosition", "MAJ_1.Direction"]) == 0
    out = capsys.readouterr().out
    # 100 cycles of jog: 0.5 mm of ramp + 10 mm/s · 0.1 s
    assert "Axis1.CommandPosition = 1.5 mm" in out
    assert "MAJ_1.Direction = 0 (FORWARD)" in out
    # an error outcome: exit 1 and the meaning; a timeout: exit 2
    assert main([*cli, "trigger", "MSO_1", "Axis=9"]) == 1
    assert "error 11: axis not configured" in capsys.readouterr().out
    assert main([*cli, "trigger", "MAJ_1", "--until", "PC", "--timeout", "0.01"]) == 2
    assert "no PC" in capsys.readouterr().err
    assert main([*cli, "write", "MAJ_1.DN=1"]) == 1
    assert "read-only" in capsys.readouterr().err
    assert main([*cli, "read", "Nope.Tag"]) == 1


def test_watch_trace_and_plot(
    cli: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*cli, "watch", "Axis1", "--count", "2", "--interval", "0"]) == 0
    out = capsys.readouterr().out
    assert out.count("Axis1.CommandPosition") == 2 and "cycle 0" in out
    assert main([*cli, "trigger", "MSO_1", "Axis=1"]) == 0
    assert main([*cli, "trigger", "MAJ_1", "Axis=1", "Speed=10", "AccelRate=100"]) == 0
    csv_path = tmp_path / "jog.csv"
    args = ["trace", "Axis1.CommandPosition", "Axis1.CommandVelocity", "-o", str(csv_path)]
    assert main([*cli, *args, "--seconds", "0.2", "--every", "10"]) == 0
    trace = Trace.read_csv(csv_path)
    assert len(trace) == 1 + 10
    assert trace.column("cycle") == [2.0 + 10 * i for i in range(11)]
    # at cycle 102 the jog has run 101 cycles: 0.5 + 10 · (0.202 - 0.1) mm
    assert trace.column("Axis1.CommandPosition")[-1] == pytest.approx(1.52, abs=1e-9)
    assert main(["plot", str(csv_path)]) == 0
    assert is_png(tmp_path / "jog.png")
