"""Exports: the JSON contract validates against its schema; the checked-in demo exports
equal a fresh export (regenerate them with ``make maps``); CSV and Markdown columns."""

from __future__ import annotations

import copy
import csv
import io
import json
from pathlib import Path

import jsonschema
import pytest

from motion_server import cli, config
from motion_server.tagmap import MAP_FORMAT, build_tagmap, export, json_schema, to_dict

ROOT = Path(__file__).resolve().parents[2]
MAPS = ROOT / "maps"


@pytest.fixture(scope="module")
def demo_dict() -> dict:
    return to_dict(build_tagmap(config.load()))


def test_json_export_validates_against_the_contract(demo_dict: dict) -> None:
    schema = json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    jsonschema.validate(demo_dict, schema)
    assert demo_dict["format"] == MAP_FORMAT == "motion-server-map/1"
    assert demo_dict["modbus"] == {
        "word_order": "big",
        "unit_id": 1,
        "function_codes": [3, 6, 16, 22, 23],
    }
    assert demo_dict["opcua"] == {"namespace_uri": "urn:motion-server:demo"}
    speed = next(t for t in demo_dict["tags"] if t["name"] == "MAJ_1.Speed")
    assert speed["access"] == "read_write"
    assert speed["opcua"] == {"node_id": "Instructions.MAJ_1.Speed"}
    dn = next(t for t in demo_dict["tags"] if t["name"] == "MAJ_1.DN")
    assert dn["modbus"]["bit"] == 1 and dn["access"] == "read"
    direction = next(t for t in demo_dict["tags"] if t["name"] == "MAJ_1.Direction")
    assert direction["enum"] == {"FORWARD": 0, "REVERSE": 1}


@pytest.mark.parametrize(
    ("path", "value"),
    [
        (("modbus", "address"), 5013),  # a REAL on an odd register
        (("modbus", "count"), 3),
        (("access",), "write"),
        (("type",), "STRING"),
    ],
)
def test_the_schema_rejects_broken_tags(
    demo_dict: dict, path: tuple[str, ...], value: object
) -> None:
    broken = copy.deepcopy(demo_dict)
    tag = next(t for t in broken["tags"] if t["name"] == "MAJ_1.Speed")
    node = tag
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(broken, json_schema())


def test_the_schema_requires_bits_on_bools_only(demo_dict: dict) -> None:
    broken = copy.deepcopy(demo_dict)
    dn = next(t for t in broken["tags"] if t["name"] == "MAJ_1.DN")
    del dn["modbus"]["bit"]
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(broken, json_schema())


def test_little_word_order_is_exported() -> None:
    text = config.load().model_dump_json()
    data = json.loads(text)
    site = config.SiteMap.model_validate(
        {**data, "modbus": {**data["modbus"], "word_order": "little"}}
    )
    exported = to_dict(build_tagmap(site))
    jsonschema.validate(exported, json_schema())
    assert exported["modbus"]["word_order"] == "little"


@pytest.mark.parametrize(
    ("fmt", "name"),
    [
        ("json", "demo-map.json"),
        ("csv", "demo-map.csv"),
        ("md", "demo-map.md"),
        ("nodeset", "demo-nodeset.xml"),
        ("kepware", "demo-kepware.csv"),
        ("ignition", "demo-ignition.json"),
        ("l5x", "demo-logix.L5X"),
    ],
)
def test_checked_in_demo_exports_equal_a_fresh_export(fmt: str, name: str) -> None:
    fresh = export(build_tagmap(config.load()), fmt)
    stored = (MAPS / name).read_text("utf-8")
    assert stored == fresh, f"maps/{name} is stale: run `make maps`"


def test_csv_columns() -> None:
    rows = list(csv.DictReader(io.StringIO(export(build_tagmap(config.load()), "csv"))))
    speed = next(r for r in rows if r["name"] == "MAJ_1.Speed")
    # MAJ (type code 6) is at 20000 + 100·5 = 20500: status bits 20500, ERR 20501,
    # FLAGS 20502-20503, EXERR 20504; command bits 20506, Axis 20508, Direction 20510,
    # Speed 20512 = 0x5020, Modbus reference 4 + (20512 + 1) = 420513
    assert speed == {
        "name": "MAJ_1.Speed",
        "address": "20512",
        "address_hex": "0x5020",
        "reference": "420513",
        "bit": "",
        "count": "2",
        "unit_id": "1",
        "type": "REAL",
        "word_order": "big",
        "access": "read_write",
        "units": "mm/s",
        "enum": "",
        "node_id": "Instructions.MAJ_1.Speed",
        "description": "speed (units/s, % of maximum, or units per master unit)",
        "bits": "",
    }
    execute = next(r for r in rows if r["name"] == "MAJ_1.Execute")
    assert (execute["address"], execute["bit"], execute["reference"]) == ("20506", "0", "420507")
    direction = next(r for r in rows if r["name"] == "MAJ_1.Direction")
    assert direction["enum"] == "0=FORWARD; 1=REVERSE"


def test_markdown_has_a_register_table_per_block() -> None:
    md = export(build_tagmap(config.load()), "md")
    assert "### MAJ_1 (MAJ)" in md
    assert "| 20512–20513 | 0x5020 | 420513 |  | `MAJ_1.Speed` | REAL | R/W | mm/s |" in md
    assert "### Axis4" in md and "`Axis4.FeedbackInput`" in md


def test_cli_map_command(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    assert cli.main(["map", "--format", "json"]) == 0
    assert json.loads(capsys.readouterr().out)["format"] == MAP_FORMAT
    out = tmp_path / "map.csv"
    assert cli.main(["map", "--format", "csv", "-o", str(out)]) == 0
    assert out.read_text("utf-8").startswith("name,address,address_hex,reference,")
