"""The kernel stays pure: no asyncio, sockets, clocks, threads or logging setup."""

from __future__ import annotations

import ast
from pathlib import Path

import motion_server.kernel

FORBIDDEN = {"asyncio", "socket", "selectors", "threading", "time", "datetime", "logging"}


def test_kernel_imports_no_io_or_clock() -> None:
    root = Path(motion_server.kernel.__file__).parent
    offenders = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        for node in ast.walk(tree):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names = [node.module]
            for name in names:
                if name.split(".")[0] in FORBIDDEN:
                    offenders.append(f"{path.name}: {name}")
    assert offenders == []
