"""Where a field was written: the one-pass index of a site map's lines."""

from __future__ import annotations

import pytest

from motion_server.config import Locations

TEXT = '''\
data_dir = "."            # 1
[site]                    # 2
name = "s"                # 3

[[axes]]                  # 5
name = "A"                # 6
max_velocity = 10.0       # 7

[[axes]]                  # 9
name = "B"
units = """mm
[[not-a-table]]
max_velocity = 1"""
max_velocity = 20.0       # 14

[modbus.access]           # 16
rules = [                 # 17
  { networks = ["10.0.0.0/8"], write = ["X"] },   # 18
  # a comment [[axes]]
  { networks = ["::1/128"], write = [             # 20
    "Y"] },
]
idle_timeout = 5          # 23

[[instructions.instances]]  # 25
name = "I"
operands.Speed = 5.0      # 27

[[instructions.instances]]  # 29
name = "J"
'''


@pytest.mark.parametrize(
    ("loc", "line"),
    [
        (("data_dir",), 1),
        (("site", "name"), 3),
        (("axes", 0), 5),
        (("axes", 0, "max_velocity"), 7),
        (("axes", 1, "max_velocity"), 14),  # not the line inside the string
        (("axes", 1, "number"), 9),  # missing: the entry's header
        (("axes", 2, "name"), 5),  # beyond the list: the first entry
        (("modbus", "access", "rules", 0, "write"), 18),
        (("modbus", "access", "rules", 1, "write"), 20),
        (("modbus", "access", "idle_timeout"), 23),
        (("instructions", "instances", 0, "operands", "Speed"), 27),
        (("instructions", "instances", 1, "name"), 30),
        (("nothing", "here"), 1),
    ],
)
def test_each_field_is_found_on_its_line(loc: tuple[int | str, ...], line: int) -> None:
    assert Locations(TEXT, "site.toml").line(loc) == line


def test_a_field_set_from_the_environment_names_the_variable() -> None:
    where = Locations(TEXT, "site.toml", {("modbus", "port"): "environment MOTION_SERVER_X"})
    assert (
        where.describe(("modbus", "port"), "bad") == "site.toml: environment MOTION_SERVER_X: bad"
    )
    assert where.describe(("site", "name"), "bad") == "site.toml:3: site.name: bad"
    more = where.overridden({("site", "name"): "option --name"})
    assert more.describe(("site", "name"), "bad") == "site.toml: option --name: bad"
