"""The site-map configuration in layers: schema, loading, assembly.

- the public names of ``motion_server.config`` stay importable from the package;
- imports point one way: no cycle runs through a module of the config or the tag map,
  whether counted at run time or by the type checker (``TYPE_CHECKING`` imports too);
- the axis fields and their defaults are written once, in the kernel's ``AxisConfig``.
"""

from __future__ import annotations

import ast
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

import motion_server
from motion_server import config
from motion_server.config import schema
from motion_server.kernel import AxisConfig

PACKAGE = Path(motion_server.__file__).parent

#: names other modules and the tests import from the package
PUBLIC = [
    "SiteMap",
    "SiteMapError",
    "load",
    "parse",
    "opcua_users",
    "load_users_file",
    "users_file_path",
    "environment_settings",
    "USERS_FILE_ENV",
    "SiteSection",
    "ControllerSection",
    "AxisSection",
    "GroupSection",
    "InstanceSection",
    "InstructionsSection",
    "WriteRule",
    "ModbusAccessSection",
    "ModbusTlsSection",
    "ModbusSection",
    "WatchdogSection",
    "AuditSection",
    "RetainSection",
    "OpcUaUser",
    "OpcUaSection",
    "UsersFile",
]


@pytest.mark.parametrize("name", PUBLIC)
def test_public_names_stay_in_the_package(name: str) -> None:
    assert hasattr(config, name)
    assert name in config.__all__


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _imports(path: Path, with_type_checking: bool) -> set[str]:
    """The motion_server modules a module imports (at any depth of its code)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    modules = set(_all_modules())
    out: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and _is_type_checking(node) and not with_type_checking:
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name in modules)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            for alias in node.names:
                sub = f"{target}.{alias.name}"
                out.add(sub if sub in modules else target)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(ast.parse(path.read_text("utf-8")))
    out.discard(name)
    return {m for m in out if m in modules}


def _all_modules() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[set[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    for v in graph:  # a few hundred modules: recursion stays shallow
        if v not in index:
            strong(v)
    return out


@pytest.mark.parametrize("with_type_checking", [False, True])
def test_no_import_cycle_runs_through_the_config_or_the_tag_map(
    with_type_checking: bool,
) -> None:
    modules = _all_modules()
    graph = {name: _imports(path, with_type_checking) for name, path in modules.items()}
    if not with_type_checking:
        # at run time, importing a.b.c first runs the package a.b: count that edge too
        for name in list(graph):
            for target in list(graph[name]):
                parent = target.rpartition(".")[0]
                if parent and parent in modules and not name.startswith(parent + "."):
                    graph[name].add(parent)
    ours = ("motion_server.config", "motion_server.tagmap")
    bad = [sorted(c) for c in _cycles(graph) if any(m.startswith(ours) for m in c)]
    assert bad == []


def test_the_tag_map_needs_only_the_schema() -> None:
    """The tag map reads site maps (the schema) and never loads or assembles them."""
    for path in (PACKAGE / "tagmap").glob("*.py"):
        for target in _imports(path, with_type_checking=True):
            if target.startswith("motion_server.config"):
                assert target == "motion_server.config.schema", (path.name, target)


@pytest.mark.parametrize(
    "first",
    ["motion_server.tagmap", "motion_server.safety.watchdog", "motion_server.config.assembly"],
)
def test_any_module_can_be_imported_first(first: str) -> None:
    code = f"import {first}, motion_server.config, motion_server.cli"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr


def test_axis_fields_and_defaults_are_the_kernels() -> None:
    kernel = {f.name: f for f in dataclasses.fields(AxisConfig)}
    section = schema.AxisSection.model_fields
    assert set(section) == set(kernel)
    defaults = AxisConfig(number=1, name="A")
    for name, info in section.items():
        if name in ("name", "number"):
            continue  # required in the kernel; the map gives the name, the number defaults
        assert info.default == getattr(defaults, name), name
    # and a default axis of the map is the kernel's default axis
    site = config.parse('[[axes]]\nname = "A"\n[[groups]]\nname = "G"\naxes = ["A"]\n')
    assert site.axis_configs() == [AxisConfig(number=1, name="A")]
