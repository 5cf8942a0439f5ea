"""Retained state: positions of absolute axes, homed flags and operand values survive a
restart; a torn or corrupt file is refused with its name and reason; ``--fresh`` ignores
it. Numbers: a 5 mm incremental MAM (defaults 10 mm/s, 100 mm/s²) lasts 0.6 s = 300
cycles of 2 ms, so after 400 cycles Axis1 rests at exactly 5 mm."""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from motion_server import config
from motion_server.config.assembly import RETAIN_HINT, assemble
from motion_server.kernel import AxisState
from motion_server.runtime import Runtime
from motion_server.safety.retain import FORMAT, RetainError, restore, retain_path

SITE = """
data_dir = "{data_dir}"

[controller]
clock = "manual"
status_log_interval = 0.0

[retain]
enabled = true
axes = ["Axis1"]

[[groups]]
name = "Group1"
axes = ["Axis1", "Axis2"]

[[axes]]
name = "Axis1"
type = "virtual"

[[axes]]
name = "Axis2"
type = "virtual"

[[instructions.instances]]
name = "MSO_1"
type = "MSO"

[[instructions.instances]]
name = "MSO_2"
type = "MSO"
operands = {{ Axis = 2 }}

[[instructions.instances]]
name = "MAM_1"
type = "MAM"

[[instructions.instances]]
name = "MAM_2"
type = "MAM"
operands = {{ Axis = 2 }}
"""


def site(tmp_path: Path) -> config.SiteMap:
    return config.parse(SITE.format(data_dir=tmp_path), "retain-test.toml")


def pulse(rt: Runtime, instance: str, **operands: float) -> None:
    for name, value in operands.items():
        rt.image.write(f"{instance}.{name}", value)
    rt.image.write(f"{instance}.Execute", False)
    rt.cycle()
    rt.image.write(f"{instance}.Execute", True)
    rt.cycle()


def run_and_save(tmp_path: Path) -> Runtime:
    rt = Runtime(site(tmp_path))
    pulse(rt, "MSO_1")
    pulse(rt, "MSO_2")
    pulse(rt, "MAM_1", MoveType=1, Position=5.0)  # Execute stays high
    pulse(rt, "MAM_2", MoveType=1, Position=5.0)
    rt.cycle(400)
    rt.ctl.axis(1).homed = True
    rt.save_retained()
    return rt


def test_positions_homed_and_operands_survive_a_restart(tmp_path: Path) -> None:
    before = run_and_save(tmp_path)
    assert before.ctl.axis(1).actual_position == pytest.approx(5.0)
    rt = Runtime(site(tmp_path))
    a1, a2 = rt.ctl.axis(1), rt.ctl.axis(2)
    assert a1.actual_position == pytest.approx(5.0)  # absolute: retained
    assert a2.actual_position == 0.0  # incremental: starts at 0
    assert a1.homed and not a2.homed
    assert rt.image.read("MAM_1.Position") == 5.0
    assert rt.image.read("MAM_1.MoveType") == 1
    assert a1.state == AxisState.AXIS_READY  # power is not retained
    # Execute was high: restored high and already seen, so nothing re-fires
    assert rt.image.read("MAM_1.Execute") is True
    rt.cycle(10)
    assert rt.image.read("MAM_1.FLAGS") == 0
    # the servo loop closes where the axis is: another 5 mm goes to 10
    pulse(rt, "MSO_1")
    pulse(rt, "MAM_1")
    rt.cycle(400)
    assert a1.actual_position == pytest.approx(10.0)


def test_no_temporary_file_is_left_behind(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["retain.json"]


@pytest.mark.parametrize(
    ("damage", "reason"),
    [
        (lambda b: b[: len(b) // 2], "torn or corrupt"),  # a torn write
        (lambda b: b.replace(b'"position": 5', b'"position": 6'), "checksum mismatch"),
        (lambda b: b"", "torn or corrupt"),
        (lambda b: b.replace(b"retain/1", b"retain/9"), "not a motion-server-retain/1"),
    ],
)
def test_a_damaged_file_is_refused_never_loaded(tmp_path: Path, damage, reason: str) -> None:  # type: ignore[no-untyped-def]
    run_and_save(tmp_path)
    path = retain_path(site(tmp_path))
    data = path.read_bytes()
    damaged = damage(data)
    assert damaged != data
    path.write_bytes(damaged)
    with pytest.raises(RetainError, match=reason) as info:
        Runtime(site(tmp_path))
    assert str(path) in str(info.value)


def test_fresh_starts_clean_even_with_a_corrupt_file(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    retain_path(site(tmp_path)).write_text("{ torn")
    rt = Runtime(site(tmp_path), fresh=True)
    assert rt.ctl.axis(1).actual_position == 0.0
    assert rt.image.read("MAM_1.Position") == 0.0


def test_a_file_of_another_site_is_refused(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    other = config.parse(
        SITE.format(data_dir=tmp_path) + '\n[site]\nname = "other"\n', "other.toml"
    )
    with pytest.raises(RetainError, match="not 'other'"):
        Runtime(other)


# -- a sound checksum over a payload of the wrong shape ----------------------------------------
def _signed(payload: object) -> str:
    """A retain file whose checksum matches ``payload``, whatever it holds (the checksum
    proves integrity, not sense: a hand-edited file re-signed is still to be judged)."""
    canonical = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    digest = hashlib.sha256(canonical.encode("utf-8")).hexdigest()
    return json.dumps({"format": FORMAT, "sha256": digest, "payload": payload})


def _payload(tmp_path: Path) -> dict[str, Any]:
    run_and_save(tmp_path)
    doc = json.loads(retain_path(site(tmp_path)).read_text())
    return dict(doc["payload"])


MALFORMED: list[tuple[str, Callable[[dict[str, Any]], None], str]] = [
    ("axes as a list", lambda p: p.__setitem__("axes", []), "axes: not a table"),
    ("operands as a list", lambda p: p.__setitem__("operands", [1]), "operands: not a table"),
    ("an axis as a list", lambda p: p["axes"].__setitem__("Axis1", [5.0]), "axes.Axis1: not a"),
    (
        "operands of an instance as a number",
        lambda p: p["operands"].__setitem__("MAM_1", 5),
        "operands.MAM_1: not a table",
    ),
    ("NaN position", lambda p: p["axes"]["Axis1"].__setitem__("position", math.nan), "NaN"),
    ("inf position", lambda p: p["axes"]["Axis1"].__setitem__("position", math.inf), "Infinity"),
    (
        "a position of 1e308",
        lambda p: p["axes"]["Axis1"].__setitem__("position", 1e308),
        "axes.Axis1.position: 1e+308 mm is beyond 2**53 encoder counts (1000 counts/mm)",
    ),
    (
        "a boolean position",
        lambda p: p["axes"]["Axis1"].__setitem__("position", True),
        "axes.Axis1.position: True is not a finite number",
    ),
    (
        "a string position",
        lambda p: p["axes"]["Axis1"].__setitem__("position", "5"),
        "axes.Axis1.position: '5' is not a finite number",
    ),
    (
        "homed as a number",
        lambda p: p["axes"]["Axis1"].__setitem__("homed", 1),
        "axes.Axis1: expected homed (a boolean)",
    ),
    ("NaN operand", lambda p: p["operands"]["MAM_1"].__setitem__("Position", math.nan), "NaN"),
    (
        "an operand beyond its type",
        lambda p: p["operands"]["MAM_1"].__setitem__("MoveType", 2**40),
        "operands.MAM_1.MoveType: 1099511627776 is outside the DINT range",
    ),
    (
        "an operand as a table",
        lambda p: p["operands"]["MAM_1"].__setitem__("Position", {"x": 1}),
        "operands.MAM_1.Position: {'x': 1} is not a finite number or boolean",
    ),
    ("an extra key", lambda p: p.__setitem__("extra", 1), "payload keys"),
    ("no axes", lambda p: p.pop("axes"), "payload keys"),
    ("a negative cycle", lambda p: p.__setitem__("cycle", -1), "cycle: not a cycle count"),
]


@pytest.mark.parametrize(
    ("damage", "reason"), [(d, r) for _, d, r in MALFORMED], ids=[name for name, _, _ in MALFORMED]
)
def test_a_signed_but_malformed_payload_is_refused_in_one_line(
    tmp_path: Path, damage: Callable[[dict[str, Any]], None], reason: str
) -> None:
    payload = _payload(tmp_path)
    damage(payload)
    path = retain_path(site(tmp_path))
    path.write_text(_signed(payload))
    # as the server starts
    with pytest.raises(RetainError) as info:
        Runtime(site(tmp_path))
    message = str(info.value)
    assert message.startswith(f"{path}: ") and "\n" not in message and reason in message
    # as check does: one line, nothing restored
    with pytest.raises(config.SiteMapError) as err:
        assemble(site(tmp_path), environ={}, probe=False)
    assert str(err.value) == f"{message} ({RETAIN_HINT})"


def test_nothing_is_applied_when_one_value_is_refused(tmp_path: Path) -> None:
    payload = _payload(tmp_path)
    payload["operands"]["MSO_2"]["Axis"] = 2**40  # refused; MAM_1's values are sound
    fresh = Runtime(site(tmp_path), fresh=True)
    with pytest.raises(RetainError, match=r"operands\.MSO_2\.Axis"):
        restore(fresh.system, payload, "retain.json")
    assert fresh.image.read("MAM_1.Position") == 0.0
    assert fresh.ctl.axis(1).actual_position == 0.0 and not fresh.ctl.axis(1).homed


def test_a_sound_payload_still_restores_through_assemble(tmp_path: Path) -> None:
    run_and_save(tmp_path)
    out = assemble(site(tmp_path), environ={}, probe=False)
    assert out.restored and out.system.ctl.axis(1).actual_position == pytest.approx(5.0)
    assert out.system.instances["MAM_1"].inputs["Position"] == 5.0


def test_a_redefined_absolute_axis_keeps_its_offset_across_a_restart(tmp_path: Path) -> None:
    """An absolute axis redefined by +100 mm (homed, or MRP) reads 105 after its 5 mm
    move and again after a restart; what it added to the raw feedback is retained too,
    so the homing sensors, fixed to the machine at raw positions, stay where they are."""
    rt = run_and_save(tmp_path)
    rt.ctl.redefine_position(rt.ctl.axis(1), 100.0, relative=True)
    rt.save_retained()
    again = Runtime(site(tmp_path))
    ax = again.ctl.axis(1)
    assert ax.actual_position == pytest.approx(105.0)
    assert ax.position_offset == 100.0
    assert again.ctl.homing.raw(ax) == pytest.approx(5.0)
