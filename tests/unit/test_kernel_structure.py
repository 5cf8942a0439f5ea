"""The kernel's structure: imports inside it point one way (no cycle, not even through
``TYPE_CHECKING``), and no module keeps state of its own (kernel state lives in the
controller, where retain and snapshots can see it)."""

from __future__ import annotations

import ast
from pathlib import Path

import motion_server.kernel

ROOT = Path(motion_server.kernel.__file__).parent


def module_name(path: Path) -> str:
    rel = path.relative_to(ROOT).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join(parts)


def resolve(current: str, is_package: bool, node: ast.ImportFrom) -> list[str]:
    """Kernel modules named by a relative ``from . import`` (absolute imports of the kernel
    count too)."""
    if node.level == 0:
        if node.module and node.module.startswith("motion_server.kernel"):
            base = node.module.removeprefix("motion_server.kernel").lstrip(".")
        else:
            return []
    else:
        parts = current.split(".") if current else []
        if not is_package:
            parts = parts[:-1]
        up = node.level - 1
        parts = parts[: len(parts) - up] if up else parts
        base = ".".join([*parts, *([node.module] if node.module else [])])
    names = [base] if base else []
    names += [f"{base}.{a.name}" if base else a.name for a in node.names]
    return names


def import_graph() -> dict[str, set[str]]:
    modules = {module_name(p): p for p in ROOT.rglob("*.py")}
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, path in modules.items():
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for target in resolve(name, path.name == "__init__.py", node):
                    if target in modules and target != name:
                        graph[name].add(target)
    return graph


def test_kernel_imports_form_no_cycle() -> None:
    graph = import_graph()
    # a package's __init__ re-exports its modules: it is not a layer of its own
    graph = {m: {t for t in deps if t != ""} for m, deps in graph.items() if m != ""}
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for t in sorted(graph.get(m, ())):
            if state.get(t) == 1:
                cycles.append([*path[path.index(t) :], t] if t in path else [m, t])
            elif t not in state:
                visit(t, [*path, t])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert cycles == []


def test_no_import_hides_under_type_checking() -> None:
    """A ``TYPE_CHECKING`` import is how a cycle hides (the controller's, before)."""
    offenders = []
    for path in ROOT.rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                offenders.append(path.name)
    assert offenders == []


#: containers that only ever hold state (a table is a dict literal, never weak)
STATE_CALLS = {"WeakKeyDictionary", "WeakValueDictionary", "WeakSet"}
MUTABLE_CALLS = {"dict", "list", "set", "defaultdict", "deque", *STATE_CALLS}


def test_no_module_level_state() -> None:
    """Module-level containers are constant tables (UPPER_CASE names), never state (and
    never weak references to kernel objects)."""
    offenders = []
    for path in ROOT.rglob("*.py"):
        tree = ast.parse(path.read_text(), str(path))
        for node in tree.body:
            if isinstance(node, ast.Assign | ast.AnnAssign):
                targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                value = node.value
                mutable = isinstance(value, ast.Dict | ast.List | ast.Set | ast.DictComp) or (
                    isinstance(value, ast.Call)
                    and ast.unparse(value.func).split(".")[-1] in MUTABLE_CALLS
                )
                for t in targets:
                    if not (mutable and isinstance(t, ast.Name)) or t.id.startswith("__"):
                        continue
                    weak = isinstance(value, ast.Call) and (
                        ast.unparse(value.func).split(".")[-1] in STATE_CALLS
                    )
                    if weak or not t.id.lstrip("_").isupper():
                        offenders.append(f"{path.name}: {t.id}")
    assert offenders == []
