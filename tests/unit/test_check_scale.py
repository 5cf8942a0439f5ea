"""``check`` does work in proportion to the size of the map, not to its square.

Counted, not timed: every Python and C function call made while a map is loaded and
assembled (``sys.setprofile``). Four times the axes may cost at most about four times the
calls; a part that compares every problem with every line of the file (as locating
problems used to) makes it sixteen. ``bench/config_check.py`` times 4,000 and 10,000 axes.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

import pytest

from motion_server import config
from motion_server.config.assembly import assemble

#: four times the axes: linear work grows 4x (plus a constant), quadratic work 16x
LIMIT = 5.0


def site_text(axes: int, axis_base: int = 1000) -> str:
    lines = [f"[modbus]\nport = 0\naxis_base = {axis_base}\n\n[opcua]\nenabled = false\n"]
    for i in range(axes):
        lines.append(f'[[axes]]\nname = "A{i}"\ntype = "virtual"\nmax_velocity = 100.0\n')
    names = ", ".join(f'"A{i}"' for i in range(axes))
    lines.append(f'[[groups]]\nname = "G"\naxes = [{names}]\n')
    return "\n".join(lines)


def calls(action: Callable[[], Any]) -> int:
    count = 0

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        nonlocal count
        if event in ("call", "c_call"):
            count += 1

    sys.setprofile(profile)
    try:
        action()
    finally:
        sys.setprofile(None)
    return count


def check(path: Path) -> None:
    with contextlib.suppress(config.SiteMapError):
        assemble(config.load(path, environ={}), environ={}, probe=False)


@pytest.mark.parametrize(
    ("what", "axis_base"),
    [
        ("accepted", 2000),
        # every axis beyond the 110th passes register 65535: one problem per axis
        ("refused", 60000),
    ],
)
def test_check_work_grows_linearly_with_the_axes(tmp_path: Path, what: str, axis_base: int) -> None:
    small, large = tmp_path / "small.toml", tmp_path / "large.toml"
    small.write_text(site_text(150, axis_base))
    large.write_text(site_text(600, axis_base))
    check(small)  # warm the caches (catalog, regular expressions)
    if what == "refused":
        with pytest.raises(config.SiteMapError, match="pass register 65535"):
            config.load(large, environ={})
    else:
        assert len(assemble(config.load(large, environ={}), probe=False).system.ctl.axes) == 600
    ratio = calls(lambda: check(large)) / calls(lambda: check(small))
    assert ratio < LIMIT, f"{what}: 4x the axes cost {ratio:.1f}x the calls"
