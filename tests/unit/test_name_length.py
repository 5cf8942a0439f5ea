"""Names are at most 40 characters, as a Logix tag name (issue 24): a 1 MB axis name passed
``check`` and made a 69 MB CSV export. Each too-long name is refused in one line naming
file, line and field; 40 characters still pass."""

from __future__ import annotations

from pathlib import Path

import pytest

from motion_server import cli
from tests.unit.test_site_map_check import assert_names, check, write

LOGIX_MAX = 40  # Logix: a tag name has at most 40 characters


def site(axis: str = "A", group: str = "G1", instance: str = "MAJ_1", watchdog: str = "WD") -> str:
    return f"""
data_dir = "{{data}}"

[modbus]
port = 0

[opcua]
enabled = false

[[axes]]
name = "{axis}"
type = "virtual"

[[groups]]
name = "{group}"
axes = ["{axis}"]

[[instructions.instances]]
name = "{instance}"
type = "MAJ"

[[watchdogs]]
name = "{watchdog}"
timeout = 1.0
group = "{group}"
"""


@pytest.mark.parametrize(
    ("field", "line", "name"),
    [
        ("axes.0.name", 11, "axis"),
        ("groups.0.name", 15, "group"),
        ("instructions.instances.0.name", 19, "instance"),
        ("watchdogs.0.name", 23, "watchdog"),
    ],
)
def test_a_name_longer_than_40_characters_is_refused_in_one_line(
    tmp_path: Path, field: str, line: int, name: str
) -> None:
    long = "N" * (LOGIX_MAX + 1)
    path = write(tmp_path, site(**{name: long}))
    message = check(path)
    assert_names(message, path, line, field)
    assert f"{LOGIX_MAX + 1} characters" in message and str(LOGIX_MAX) in message


def test_a_megabyte_name_is_refused_without_echoing_it(tmp_path: Path) -> None:
    path = write(tmp_path, site(axis="A" * 1_000_000))
    message = check(path)
    assert_names(message, path, 11, "axes.0.name")
    assert len(message) < 400


def test_names_of_40_characters_pass(tmp_path: Path) -> None:
    names = {k: k[0].upper() + "x" * (LOGIX_MAX - 1) for k in ("axis", "group", "watchdog")}
    path = write(tmp_path, site(instance="I" * LOGIX_MAX, **names))
    assert cli.main(["check", str(path)]) == 0
