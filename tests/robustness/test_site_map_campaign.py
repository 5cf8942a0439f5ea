"""Mutated site maps: every map is refused in one line per problem, or it runs.

A campaign of seeded mutations of one sound site map (``MOTION_FUZZ_SEED``, default
20250131; ``MOTION_FUZZ_LONG=1`` runs ten times as many): wrong types, missing and
unknown keys, bad references, extreme numbers and invalid TOML. Each map is written to a
file and checked exactly as ``motion-server check`` does (load, then assemble: system,
tag map, watchdogs, users, files, ports). Then:

- refused: a :class:`SiteMapError` whose lines each name the file (and, when the TOML
  parsed, a line and a field): never another exception;
- accepted: the system runs 1,000 cycles with every instruction triggered, then the
  programmed stop of leaving run mode, without an exception, and every axis position
  stays finite.
"""

from __future__ import annotations

import copy
import json
import math
import os
import random
import re
import sys
import tomllib
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from motion_server import config
from motion_server.config.assembly import assemble
from motion_server.kernel.group import OperatingMode
from motion_server.safety.passwords import hash_password

SEED = int(os.environ.get("MOTION_FUZZ_SEED", "20250131"))
SCALE = 10 if os.environ.get("MOTION_FUZZ_LONG") else 1
MAPS = 320 * SCALE
CYCLES = 1000
#: cycles of the programmed stop after the run (leaving run mode, as at shutdown)
STOP_CYCLES = 500

BASE = """
data_dir = "{data}"

[site]
name = "campaign"

[controller]
clock = "manual"
status_log_interval = 0.0

[[axes]]
name = "Servo"
type = "servo"
conversion_constant = 1000.0
max_velocity = 500.0
max_acceleration = 5000.0
max_deceleration = 5000.0
programmed_stop_mode = "fast_disable"
following_error_limit = 10.0

[[axes]]
name = "Rotary"
type = "servo"
units = "deg"
rollover = 360.0
max_velocity = 3600.0
max_acceleration = 36000.0
max_deceleration = 36000.0
max_jerk = 1000000.0

[[axes]]
name = "Master"
type = "virtual"
max_velocity = 1000.0

[[axes]]
name = "Wheel"
type = "feedback_only"
conversion_constant = 100.0
feedback_signal = "sine"
signal_amplitude = 10.0
signal_frequency = 2.0

[[groups]]
name = "Fast"
coarse_update_period_ms = 2.0
axes = ["Servo", "Rotary", "Master"]

[[groups]]
name = "Slow"
coarse_update_period_ms = 4.0
axes = ["Wheel"]

[[instructions.instances]]
name = "PowerServo"
type = "MSO"
operands = {{ Axis = 1 }}

[[instructions.instances]]
name = "PowerRotary"
type = "MC_Power"
operands = {{ Axis = 2 }}

[[instructions.instances]]
name = "PowerMaster"
type = "MSO"
operands = {{ Axis = 3 }}

[[instructions.instances]]
name = "JogMaster"
type = "MAJ"
operands = {{ Axis = 3, Speed = 100.0, AccelRate = 1000.0, DecelRate = 1000.0 }}

[[instructions.instances]]
name = "Gear"
type = "MAG"
operands = {{ SlaveAxis = 1, MasterAxis = 3, Ratio = 0.5 }}

[[instructions.instances]]
name = "MoveRotary"
type = "MC_MoveVelocity"
operands = {{ Axis = 2, Velocity = 90.0, Acceleration = 900.0, Deceleration = 900.0 }}

[[instructions.instances]]
name = "StopAll"
type = "MGS"
operands = {{ Group = 1, StopMode = 0 }}

[[watchdogs]]
name = "Hmi"
timeout = 0.5
group = "Fast"

[modbus]
port = 0

[[modbus.access.rules]]
networks = ["10.0.0.0/8"]
write = ["Instructions", "Hmi", "5000-5099"]

[opcua]
port = 0
data_dir = "{data}/opcua"

[[opcua.users]]
name = "operator"
role = "operator"
password_hash = "{hash}"

[audit]
enabled = true
path = "audit.jsonl"

[retain]
enabled = true
path = "state/retain.json"
axes = ["Servo", "Master"]
"""

EXTREMES: list[Any] = [
    0,
    -0.0,
    -1,
    1e-300,
    5e-324,
    1e-12,
    0.5,
    1.5,
    1e12,
    3.4e38,
    3.5e38,
    1e300,
    1.7976931348623157e308,
    -1e308,
    math.inf,
    -math.inf,
    math.nan,
    2**31,
    2**63,
    -(2**63),
    2**64,
    65536,
]
OTHER_TYPES: list[Any] = ["text", "", True, False, 7, 2.5, [], [1, "a"], {}, {"x": 1}]


# -- a small TOML writer (the campaign edits data, then writes it back) -----------------------
def _key(k: str) -> str:
    return k if re.fullmatch(r"[A-Za-z0-9_-]+", k) else json.dumps(k)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    return json.dumps(str(v))


def _tables(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def dump(data: dict[str, Any], path: tuple[str, ...] = ()) -> str:
    lines = [f"{_key(k)} = {_value(v)}" for k, v in data.items() if not _is_table(v)]
    for k, v in data.items():
        name = ".".join(_key(p) for p in (*path, k))
        if isinstance(v, dict):
            lines += ["", f"[{name}]", dump(v, (*path, k))]
        elif _tables(v):
            for item in v:
                lines += ["", f"[[{name}]]", dump(item, (*path, k))]
    return "\n".join(lines)


def _is_table(v: Any) -> bool:
    return isinstance(v, dict) or _tables(v)


# -- mutations ------------------------------------------------------------------------------------
KeyPath = tuple[Any, ...]


def _paths(node: Any, here: KeyPath = ()) -> list[KeyPath]:
    """Every key or index below ``node`` (containers and leaves)."""
    out: list[KeyPath] = []
    items: list[tuple[Any, Any]] = []
    if isinstance(node, dict):
        items = list(node.items())
    elif isinstance(node, list):
        items = list(enumerate(node))
    for k, v in items:
        out.append((*here, k))
        out += _paths(v, (*here, k))
    return out


def _parent(data: Any, path: KeyPath) -> Any:
    for k in path[:-1]:
        data = data[k]
    return data


def _numeric(data: Any) -> list[KeyPath]:
    return [
        p
        for p in _paths(data)
        if isinstance(_parent(data, p)[p[-1]], int | float)
        and not isinstance(_parent(data, p)[p[-1]], bool)
    ]


def wrong_type(r: random.Random, data: dict[str, Any]) -> str:
    path = r.choice(_paths(data))
    value = _parent(data, path)[path[-1]]
    choices = [v for v in OTHER_TYPES if type(v) is not type(value)]
    _parent(data, path)[path[-1]] = copy.deepcopy(r.choice(choices))
    return dump(data)


def missing_key(r: random.Random, data: dict[str, Any]) -> str:
    path = r.choice([p for p in _paths(data) if isinstance(_parent(data, p), dict)])
    del _parent(data, path)[path[-1]]
    return dump(data)


def unknown_key(r: random.Random, data: dict[str, Any]) -> str:
    tables = [()] + [p for p in _paths(data) if isinstance(_parent(data, p)[p[-1]], dict)]
    path = r.choice(tables)
    table = data
    for k in path:
        table = table[k]
    table[r.choice(["colour", "max_speed", "Axis", "name2", "enabled_", "unit"])] = r.choice(
        OTHER_TYPES[:7]
    )
    return dump(data)


def extreme_number(r: random.Random, data: dict[str, Any]) -> str:
    for _ in range(r.choice([1, 1, 2, 3])):
        path = r.choice(_numeric(data))
        _parent(data, path)[path[-1]] = r.choice(EXTREMES)
    return dump(data)


def bad_reference(r: random.Random, data: dict[str, Any]) -> str:
    kind = r.randrange(11)
    axes, groups = data["axes"], data["groups"]
    instances = data["instructions"]["instances"]
    if kind == 0:
        r.choice(groups)["axes"].append(r.choice(["Nobody", "Servo", "Wheel"]))
    elif kind == 1:
        r.choice(groups)["axes"] = []
    elif kind == 2:
        data["watchdogs"][0]["group"] = r.choice(["Nobody", "fast", ""])
    elif kind == 3:
        data["retain"]["axes"].append(r.choice(["Nobody", "servo"]))
    elif kind == 4:
        data["modbus"]["access"]["rules"][0]["write"].append(
            r.choice(["Nobody", "JogMaster.Nothing", "Axes", "Servo", "Clock", "99999-100000"])
        )
    elif kind == 5:
        inst = r.choice(instances)
        key = next(iter(inst["operands"]))
        inst["operands"][key] = r.choice([0, 99, -1, 1.5, 1e20, 2**31, True])
    elif kind == 6:
        r.choice(axes)["number"] = r.choice([1, 2, 4, 65535, 0])
    elif kind == 7:
        r.choice(groups)["number"] = r.choice([1, 2, 255, 256])
    elif kind == 8:
        victim = r.choice([*axes, *groups, *instances, data["watchdogs"][0]])
        victim["name"] = r.choice(
            [
                "Servo",
                "Fast",
                "JogMaster",
                "Hmi",
                "Clock",
                "MAJ_1",
                "bad name",
                "N" * 41,
                "N" * 10**6,
            ]
        )
    elif kind == 9:
        data["instructions"]["every_type"] = True
        data["watchdogs"][0]["name"] = r.choice(["MAJ_1", "MSO_1", "Hmi2"])
    else:
        data["opcua"]["users"][0]["password_hash"] = r.choice(
            [
                "scrypt$1048576$32$16$c2FsdHNhbHQ=$a2V5a2V5a2V5a2V5a2V5a2V5",
                "scrypt$3$8$1$c2FsdHNhbHQ=$a2V5a2V5a2V5a2V5a2V5a2V5",
                "scrypt$524288$1$1$c2FsdHNhbHQ=$a2V5a2V5a2V5a2V5a2V5a2V5",
                "plain",
            ]
        )
    return dump(data)


def invalid_toml(r: random.Random, data: dict[str, Any]) -> str:
    text = dump(data)
    kind = r.randrange(6)
    if kind == 0:
        return text[: r.randrange(len(text))]
    if kind == 1:
        i = r.randrange(len(text))
        return (
            text[:i] + r.choice(['"', "[", "]]", "=", "\n[[", "{", "\\", "\x00", "'''"]) + text[i:]
        )
    if kind == 2:
        return text + "\n[site]\nname = 'again'\n"
    if kind == 3:
        depth = r.choice([100, 900, 3000])
        return text + "\nnested = " + "[" * depth + "]" * depth + "\n"
    if kind == 4:
        return text + "\n" + r.choice(["x = ", "a.b = 1\na = 2", "y = 1979-05-27", "[[axes]"])
    return text.replace("=", "==", 1)


MUTATIONS: list[Callable[[random.Random, dict[str, Any]], str]] = [
    wrong_type,
    missing_key,
    unknown_key,
    extreme_number,
    extreme_number,
    bad_reference,
    bad_reference,
    invalid_toml,
]


# -- the campaign ---------------------------------------------------------------------------------
#: instruction types that power axes (triggered first) and that stop groups (last)
POWER = {"MSO", "MC_Power"}
STOPS = {"MGS", "MGSD", "MGSP", "MC_Stop", "MAS"}


def run_accepted(assembly: Any) -> None:
    """1,000 cycles: drives on, then every other instruction triggered in turn, the
    watchdogs fed until cycle 600 (so they trip), the stopping instructions at cycle
    700; then the programmed stop of leaving run mode."""
    system = assembly.system
    ctl = system.ctl
    start: dict[str, int] = {}
    for i, (name, inst) in enumerate(system.instances.items()):
        start[name] = 2 if inst.TYPE in POWER else 700 if inst.TYPE in STOPS else 10 + 3 * i
    for k in range(CYCLES):
        for name, inst in system.instances.items():
            if k == start[name]:
                inst.inputs[inst.TRIGGER] = True
        for wd in assembly.watchdogs.values():
            if k < 600 and k % 50 == 0:
                wd.beat(k)
            wd.check()
        system.cycle()
    stops = ctl.set_mode(OperatingMode.PROGRAM)
    for _ in range(STOP_CYCLES):
        if all(s.complete for s in stops):
            break
        system.cycle()
    for values in (ctl.cmd_pos, ctl.act_pos, ctl.cmd_vel, ctl.act_vel):
        assert all(math.isfinite(float(v)) for v in values), values


def test_mutated_site_maps_are_refused_in_one_line_or_run(tmp_path: Path) -> None:
    r = random.Random(SEED)
    users_hash = hash_password("campaign", n=2**4, r=1)
    base_text = BASE.format(data=tmp_path / "data", hash=users_hash)
    base = tomllib.loads(base_text)
    # the unmutated map is accepted and runs
    sound = tmp_path / "sound.toml"
    sound.write_text(dump(base))
    run_accepted(assemble(config.load(sound, environ={}), environ={}))

    results: Counter[str] = Counter()
    for n in range(MAPS):
        mutate = r.choice(MUTATIONS)
        text = mutate(r, copy.deepcopy(base))
        path = tmp_path / f"map{n:04d}.toml"
        path.write_text(text, "utf-8")
        try:
            site = config.load(path, environ={})
            assembly = assemble(site, environ={})
        except config.SiteMapError as exc:
            lines = str(exc).splitlines()
            assert 1 <= len(lines) <= 21, (mutate.__name__, text, lines)
            for line in lines:
                assert line.startswith(f"{path}"), (mutate.__name__, line)
                assert re.match(rf"^{re.escape(str(path))}(:\d+)?: \S", line), line
                assert "Traceback" not in line
            results[f"{mutate.__name__}: refused"] += 1
            continue
        run_accepted(assembly)
        results[f"{mutate.__name__}: accepted, ran {CYCLES} cycles"] += 1
    for key, count in sorted(results.items()):
        print(f"{key}: {count}")
    refused = sum(v for k, v in results.items() if k.endswith("refused"))
    assert sum(results.values()) == MAPS >= 300
    # both outcomes are exercised, not just one
    assert refused >= MAPS // 4 and MAPS - refused >= MAPS // 10


@pytest.mark.parametrize("depth", [500, 5000, 100_000])
def test_deeply_nested_toml_is_refused_in_lines_naming_the_file(tmp_path: Path, depth: int) -> None:
    """Nesting the TOML parser cannot follow is one line; what it can parse is judged
    like any other map (here: no axes, no groups, an unknown key)."""
    path = tmp_path / "nested.toml"
    path.write_text("a = " + "[" * depth + "]" * depth + "\n")
    with pytest.raises(config.SiteMapError) as err:
        config.load(path, environ={})
    lines = str(err.value).splitlines()
    assert all(line.startswith(str(path)) for line in lines)
    if depth > sys.getrecursionlimit():
        assert lines == [f"{path}: invalid TOML: arrays or tables nested too deeply"]
