"""container/heartbeat.py: register decoding and the health rule, without a server."""

from __future__ import annotations

import importlib.util
import json
import os
import socket
import struct
import sys
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "container" / "heartbeat.py"


def _load() -> ModuleType:
    spec = importlib.util.spec_from_file_location("container_heartbeat", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


hb = _load()


@pytest.mark.parametrize(
    ("registers", "tag_type", "word_order", "expected"),
    [
        ([0x0001, 0x2345], "UDINT", "big", 0x00012345),
        ([0x2345, 0x0001], "UDINT", "little", 0x00012345),
        ([0xFFFF, 0xFFFF], "UDINT", "big", 2**32 - 1),
        ([0xFFFF, 0xFFFE], "DINT", "big", -2),
        ([0xFFFF], "INT", "big", -1),
        ([0x3FC0, 0x0000], "REAL", "big", 1.5),  # 1.5 = 0x3FC00000
        ([0x0000, 0x3FC0], "REAL", "little", 1.5),
        ([0x3FF8, 0, 0, 0], "LREAL", "big", 1.5),  # 1.5 = 0x3FF8000000000000
        ([0, 0, 0, 0x3FF8], "LREAL", "little", 1.5),
    ],
)
def test_decode(registers: list[int], tag_type: str, word_order: str, expected: float) -> None:
    assert hb.decode(registers, tag_type, word_order) == expected


def test_decode_round_trips_every_udint_word_pattern() -> None:
    for value in (0, 1, 0xFFFF, 0x10000, 0x7FFFFFFF, 0x80000000):
        hi, lo = struct.unpack(">HH", struct.pack(">I", value))
        assert hb.decode([hi, lo], "UDINT", "big") == value
        assert hb.decode([lo, hi], "UDINT", "little") == value


MAP: dict[str, Any] = {
    "format": "motion-server-map/1",
    "modbus": {"word_order": "big", "unit_id": 1},
    "tags": [
        {"name": "Controller.Heartbeat", "type": "UDINT", "modbus": {"address": 10, "count": 2}},
        {
            "name": "Clock.Mode",
            "type": "INT",
            "modbus": {"address": 20, "count": 1},
            "enum": {"REALTIME": 0, "MANUAL": 1, "SCALED": 2},
        },
    ],
}


class FakeReader:
    """Answers reads of the two tags from scripted values."""

    def __init__(self, heartbeats: list[int], clock_mode: int, ready: int | None = None) -> None:
        self.map = MAP
        if ready is not None:
            self.map = {**MAP, "tags": [*MAP["tags"], READY]}
        self.where = "fake:5020"
        self.heartbeats = heartbeats
        self.clock_mode = clock_mode
        self.ready = ready
        self.names: list[str] = []

    def read(self, tag: dict[str, Any]) -> int:
        self.names.append(tag["name"])
        if tag["name"] == "Clock.Mode":
            return self.clock_mode
        if tag["name"] == "Diagnostics.Ready":
            assert self.ready is not None
            return self.ready
        return self.heartbeats.pop(0)


READY = {
    "name": "Diagnostics.Ready",
    "type": "BOOL",
    "modbus": {"address": 30, "count": 1, "bit": 0},
}


def test_a_controller_that_is_not_ready_is_unhealthy_whatever_its_heartbeat() -> None:
    reader = FakeReader([100, 350], clock_mode=0, ready=0)
    with pytest.raises(hb.Unhealthy, match=r"Diagnostics\.Ready is 0 at fake:5020"):
        hb.check(reader, 0.0, require_increase=False)
    assert reader.names == ["Diagnostics.Ready"]  # the heartbeat was not even read


def test_ready_and_counting_is_healthy_and_ready_is_read_first() -> None:
    reader = FakeReader([100, 350], clock_mode=0, ready=1)
    assert "100 -> 350" in hb.check(reader, 0.0, require_increase=True)
    assert reader.names[0] == "Diagnostics.Ready"
    reader = FakeReader([7, 7], clock_mode=1, ready=1)
    assert "manual clock" in hb.check(reader, 0.0, require_increase=False)


def test_wait_tries_again_until_healthy(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    path = tmp_path / "map.json"
    path.write_text(json.dumps(MAP))
    answers: list[str | Exception] = [hb.Unhealthy("not yet"), hb.Unhealthy("not yet"), "fine"]

    def attempt(*_: Any) -> str:
        answer = answers.pop(0)
        if isinstance(answer, Exception):
            raise answer
        return answer

    monkeypatch.setattr(hb, "attempt", attempt)
    monkeypatch.setattr(hb, "RETRY_PAUSE", 0.01)
    assert hb.main(["--map-json", str(path), "--port", "1", "--wait", "5"]) == 0
    assert answers == []


class FakeTime:
    """time.monotonic and time.sleep of a clock that moves only when slept on."""

    def __init__(self) -> None:
        self.now = 0.0

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def test_wait_gives_up_with_the_last_reason(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "map.json"
    path.write_text(json.dumps(MAP))
    tries: list[float] = []
    clock = FakeTime()

    def attempt(*_: Any) -> str:
        tries.append(clock.now)
        raise hb.Unhealthy(f"try {len(tries)} refused")

    monkeypatch.setattr(hb, "attempt", attempt)
    monkeypatch.setattr(hb, "time", clock)
    assert hb.main(["--map-json", str(path), "--port", "1", "--wait", "1.2"]) == 1
    # 0.5 s apart while another pause still ends within 1.2 s: at 0, 0.5 and 1.0 s
    assert tries == [0.0, 0.5, 1.0]
    err = capsys.readouterr().err
    assert err == "unhealthy: try 3 refused (after 3 attempts in 1.2 s)\n"


def test_the_map_cache_is_reused_while_nothing_it_depends_on_changed(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    made: list[str] = []

    def load_map(path: str | None) -> dict[str, Any]:
        assert path is None
        made.append("map")
        return MAP

    def site_ports() -> tuple[int, int]:
        made.append("ports")
        return 5020 + len(made), 4840

    monkeypatch.setattr(hb, "load_map", load_map)
    monkeypatch.setattr(hb, "site_ports", site_ports)
    for name in [n for n in os.environ if n.startswith("MOTION_SERVER_")]:
        monkeypatch.delenv(name)
    cache = str(tmp_path / "cache.json")
    assert hb.cached_map_and_ports(cache) == (MAP, (5022, 4840))
    assert made == ["map", "ports"]
    assert hb.cached_map_and_ports(cache) == (MAP, (5022, 4840))  # from the file
    assert made == ["map", "ports"]
    # another setting: made again
    monkeypatch.setenv("MOTION_SERVER_MODBUS_PORT", "1502")
    assert hb.cached_map_and_ports(cache) == (MAP, (5024, 4840))
    assert hb.cached_map_and_ports(cache) == (MAP, (5024, 4840))
    assert len(made) == 4
    # the site map file it names, then that file changed
    site = tmp_path / "site.toml"
    site.write_text("[[axes]]\n")
    monkeypatch.setenv("MOTION_SERVER_MAP", str(site))
    hb.cached_map_and_ports(cache)
    assert len(made) == 6
    hb.cached_map_and_ports(cache)
    assert len(made) == 6
    site.write_text("[[axes]]\nname = 'A'\n")
    hb.cached_map_and_ports(cache)
    assert len(made) == 8
    # a damaged cache file is made again, not trusted
    Path(cache).write_text("{not json")
    hb.cached_map_and_ports(cache)
    assert len(made) == 10
    assert json.loads(Path(cache).read_text())["map"] == MAP


def test_the_opcua_port_must_accept_a_connection() -> None:
    with socket.socket() as listening:
        listening.bind(("127.0.0.1", 0))
        listening.listen()
        port = listening.getsockname()[1]
        hb.check_listening("127.0.0.1", port, 1.0)
    # the same port, closed now: refused
    with pytest.raises(hb.Unhealthy, match=f"OPC UA port 127.0.0.1:{port} does not accept"):
        hb.check_listening("127.0.0.1", port, 1.0)


def test_a_counting_heartbeat_is_healthy() -> None:
    message = hb.check(FakeReader([100, 350], clock_mode=0), 0.0, require_increase=True)
    assert "100 -> 350" in message


def test_a_stuck_heartbeat_in_realtime_is_unhealthy() -> None:
    with pytest.raises(hb.Unhealthy, match="did not increase: 100 -> 100"):
        hb.check(FakeReader([100, 100], clock_mode=0), 0.0, require_increase=False)


def test_a_still_heartbeat_in_manual_clock_is_healthy_unless_increase_is_required() -> None:
    assert "manual clock" in hb.check(FakeReader([7, 7], 1), 0.0, require_increase=False)
    with pytest.raises(hb.Unhealthy):
        hb.check(FakeReader([7, 7], 1), 0.0, require_increase=True)


def test_the_diagnostics_heartbeat_comes_first() -> None:
    reader = FakeReader([1, 2], 0)
    diagnostics = {**MAP["tags"][0], "name": "Diagnostics.Heartbeat"}
    reader.map = {**MAP, "tags": [*MAP["tags"], diagnostics]}
    assert hb.check(reader, 0.0, require_increase=True).startswith("Diagnostics.Heartbeat 1 -> 2")
    assert reader.names == ["Diagnostics.Heartbeat", "Diagnostics.Heartbeat"]


def test_scaled_clock_is_not_manual() -> None:
    with pytest.raises(hb.Unhealthy):
        hb.check(FakeReader([7, 7], clock_mode=2), 0.0, require_increase=False)


def test_a_map_without_heartbeat_is_unhealthy() -> None:
    reader = FakeReader([1, 2], 0)
    reader.map = {**MAP, "tags": MAP["tags"][1:]}
    with pytest.raises(hb.Unhealthy, match=r"no Diagnostics\.Heartbeat or Controller\.Heartbeat"):
        hb.check(reader, 0.0, require_increase=False)


def test_a_map_of_another_format_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "map.json"
    path.write_text('{"format": "something-else/2", "tags": []}')
    with pytest.raises(hb.Unhealthy, match="something-else/2"):
        hb.load_map(str(path))


def test_an_unreachable_server_is_reported_not_raised(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "map.json"
    path.write_text(json.dumps(MAP))
    # port 1 on 127.0.0.1: nothing listens there, the connection is refused at once
    rc = hb.main(["--map-json", str(path), "--port", "1", "--timeout", "0.5"])
    assert rc == 1
    assert "unhealthy: cannot connect to Modbus server at 127.0.0.1:1" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("value", "tag_type", "word_order", "registers"),
    [
        (1, "DINT", "big", [0x0000, 0x0001]),
        (1, "DINT", "little", [0x0001, 0x0000]),
        (-2, "DINT", "big", [0xFFFF, 0xFFFE]),
        (100.0, "REAL", "big", [0x42C8, 0x0000]),  # 100.0 = 0x42C80000
        (5000.0, "REAL", "little", [0x4000, 0x459C]),  # 5000.0 = 0x459C4000
        (1, "BOOL", "big", [0x0001]),
    ],
)
def test_encode(value: float, tag_type: str, word_order: str, registers: list[int]) -> None:
    assert hb.encode(value, tag_type, word_order) == registers
    assert hb.decode(registers, tag_type, word_order) == value
