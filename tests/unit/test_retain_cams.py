"""Retained cam tables: the points and Length a client wrote survive a restart; the
profiles do not (every ProfileStatus starts at 0: docs/semantics.md); a retain file with
a malformed cam entry is refused in one line naming it."""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from motion_server import config
from motion_server.runtime import Runtime
from motion_server.safety.retain import FORMAT, RetainError, retain_path

SITE = """
data_dir = "{data_dir}"

[controller]
clock = "manual"
status_log_interval = 0.0

[retain]
enabled = true

[[groups]]
name = "Group1"
axes = ["Axis1"]

[[axes]]
name = "Axis1"
type = "virtual"

[[cams]]
name = "Cam1"
capacity = 4
points = [[0, 0, 0], [10, 5, 0]]
"""


def site(tmp_path: Path) -> config.SiteMap:
    return config.parse(SITE.format(data_dir=tmp_path), "retain-cams.toml")


def run_and_save(tmp_path: Path) -> Runtime:
    rt = Runtime(site(tmp_path))
    # a third point, 0.25 (exact in a REAL), and Length 3, as a client writes them
    rt.image.write_many(
        [("Cam1.Master[2]", 20.0), ("Cam1.Slave[2]", 0.25), ("Cam1.SegmentType[2]", 1)]
    )
    rt.image.write("Cam1.Length", 3)
    rt.cycle()
    rt.ctl.cams.calculate(1, 0, 3, 0.0, 0.0, 1)
    rt.cycle()
    assert rt.image.read("Cam1.ProfileStatus") == 2
    rt.save_retained()
    return rt


def test_points_and_length_survive_a_restart_the_profile_does_not(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    rt = Runtime(site(tmp_path))
    table = rt.ctl.cams.tables[1]
    assert table.master == [0.0, 10.0, 20.0, 0.0]
    assert table.slave == [0.0, 5.0, 0.25, 0.0]
    assert table.segment == [0, 0, 1, 0]
    assert table.length == 3
    assert rt.image.read("Cam1.Slave[2]") == 0.25
    assert rt.image.read("Cam1.ProfileStatus") == 0  # recomputed by MCCP, not retained
    assert rt.ctl.cams.slots[1].profile is None


def test_a_file_without_cams_still_restores(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    path = retain_path(site(tmp_path))
    payload = json.loads(path.read_text())["payload"]
    del payload["cams"]  # written before the site had cam tables
    path.write_text(_signed(payload))
    rt = Runtime(site(tmp_path))
    assert rt.ctl.cams.tables[1].master == [0.0, 10.0, 0.0, 0.0]  # the site map's points
    assert rt.ctl.cams.tables[1].length == 2


def _signed(payload: object) -> str:
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    digest = hashlib.sha256(canonical.encode("utf-8")).hexdigest()
    return json.dumps({"format": FORMAT, "sha256": digest, "payload": payload})


MALFORMED: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("cams as a list", lambda p: p.__setitem__("cams", []), "cams: not a table"),
    ("a missing key", lambda p: p["cams"]["Cam1"].pop("slave"), "cams.Cam1: expected"),
    ("a NaN master", lambda p: p["cams"]["Cam1"]["master"].__setitem__(1, math.nan), "NaN"),
    (
        "a master beyond a REAL",
        lambda p: p["cams"]["Cam1"]["master"].__setitem__(1, 1e39),
        "cams.Cam1.master[1]: 1e+39 is not a finite REAL",
    ),
    (
        "a fractional segment type",
        lambda p: p["cams"]["Cam1"]["segment"].__setitem__(0, 0.5),
        "cams.Cam1.segment[0]: 0.5 is not a DINT",
    ),
    (
        "a length beyond a DINT",
        lambda p: p["cams"]["Cam1"].__setitem__("length", 2**40),
        "cams.Cam1.length: 1099511627776 is not a DINT",
    ),
]


@pytest.mark.parametrize(
    ("damage", "reason"), [(d, r) for _, d, r in MALFORMED], ids=[name for name, _, _ in MALFORMED]
)
def test_a_malformed_cam_entry_is_refused_in_one_line(
    tmp_path: Path, damage: Callable[[dict[str, Any]], None], reason: str
) -> None:
    run_and_save(tmp_path)
    path = retain_path(site(tmp_path))
    payload = json.loads(path.read_text())["payload"]
    damage(payload)
    path.write_text(_signed(payload))
    with pytest.raises(RetainError) as info:
        Runtime(site(tmp_path))
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and reason in message
