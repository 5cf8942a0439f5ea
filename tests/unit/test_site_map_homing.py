"""Homing in the site map: the ``[[axes]]`` homing fields, the checks a map is held to,
and the tags (the sensors' BOOLs only on axes that have the sensor, the homing
configuration in every axis's configuration block, nothing else moved)."""

from __future__ import annotations

import pytest

from motion_server import config
from motion_server.config.schema import SiteMapError
from motion_server.instructions import TagType
from motion_server.kernel.enums import HomeDirection, HomeMode, HomeSequence
from motion_server.tagmap import Access, TagImage, build_tagmap

BASE = """
[[groups]]
name = "G"
axes = ["Plain", "Homed"]

[[axes]]
name = "Plain"
type = "virtual"

[[axes]]
name = "Homed"
type = "virtual"
{homing}
"""

HOMING = """
home_mode = "active"
home_sequence = "switch_then_marker"
home_direction = "unidirectional_reverse"
home_position = 5.0
home_offset = -1.5
home_speed = 20.0
home_return_speed = 2.0
home_switch = 100.0
home_switch_width = 4.0
marker_interval = 2.0
marker_offset = 0.5
"""


def site(homing: str = HOMING) -> config.SiteMap:
    return config.parse(BASE.format(homing=homing), "site.toml")


def problems(homing: str) -> str:
    with pytest.raises(SiteMapError) as err:
        site(homing)
    return str(err.value)


def test_homing_fields_reach_the_axis_configuration() -> None:
    cfg = site().axis_configs()[1]
    assert cfg.home_mode == HomeMode.ACTIVE
    assert cfg.home_sequence == HomeSequence.SWITCH_THEN_MARKER
    assert cfg.home_direction == HomeDirection.UNIDIRECTIONAL_REVERSE
    assert (cfg.home_position, cfg.home_offset, cfg.home_speed) == (5.0, -1.5, 20.0)
    assert (cfg.home_switch, cfg.home_switch_width) == (100.0, 4.0)
    assert (cfg.marker_interval, cfg.marker_offset) == (2.0, 0.5)


@pytest.mark.parametrize(
    ("homing", "field", "why"),
    [
        ('home_sequence = "switch"\nhome_speed = 1.0', "home_sequence", "needs home_switch"),
        ('home_sequence = "marker"\nhome_speed = 1.0', "home_sequence", "needs marker_interval"),
        ('home_sequence = "marker"\nmarker_interval = 1.0', "home_speed", "home speed > 0"),
        (
            'home_sequence = "marker"\nmarker_interval = 1.0\nhome_speed = 1.0',
            "home_return_speed",
            "return speed",
        ),
        ('home_mode = "absolute"\nhome_sequence = "marker"', "home_sequence", "immediate only"),
        ("home_switch = 3.0", "home_switch_width", "width"),
        # within the axis's limits (max_velocity 1000, max_acceleration and deceleration
        # 10000 by default)
        ("home_speed = 1000.5", "home_speed", "must not exceed max_velocity (1000)"),
        ("home_return_speed = 2000.0", "home_return_speed", "max_velocity (1000)"),
        ("home_acceleration = 10001.0", "home_acceleration", "max_acceleration (10000)"),
        ("home_deceleration = 1e5", "home_deceleration", "max_deceleration (10000)"),
        ('home_mode = "passivity"', "home_mode", ""),
    ],
)
def test_a_homing_the_axis_cannot_run_is_a_map_error(homing: str, field: str, why: str) -> None:
    message = problems(homing)
    assert f"axes.1.{field}" in message
    assert why in message


def test_rotary_homing_positions_lie_in_the_turn() -> None:
    message = problems('units = "deg"\nrollover = 360.0\nhome_position = 360.0')
    assert "axes.1.home_position" in message
    message = problems("rollover = 360.0\nhome_switch = 10.0\nhome_switch_width = 360.0")
    assert "axes.1.home_switch_width" in message


def test_sensor_tags_exist_only_on_axes_with_sensors() -> None:
    tags = build_tagmap(site())
    for name in ("HomeSwitch", "Marker"):
        tag = tags.tag(f"Homed.{name}")
        assert (tag.type, tag.access) == (TagType.BOOL, Access.READ)
        assert f"Plain.{name}" not in tags
    # the BOOLs come after the words: every other field keeps the registers of an axis
    # without sensors
    plain = tags.block_at(tags.tag("Plain.Number").address)
    homed = tags.block_at(tags.tag("Homed.Number").address)
    assert plain is not None and homed is not None
    for field in ("Number", "AxisState", "MotionStatus", "ActualPosition", "PositionError"):
        assert tags.tag(f"Homed.{field}").address - homed.base == (
            tags.tag(f"Plain.{field}").address - plain.base
        )


def test_homing_configuration_tags() -> None:
    tags = build_tagmap(site())
    assert tags.tag("Homed.HomeSequence").enum is HomeSequence
    image = TagImage(tags, site().build())
    assert image.read("Homed.HomeSequence") == 3
    assert image.read("Homed.HomeDirection") == 2
    assert image.read("Homed.HomePosition") == 5.0
    assert image.read("Homed.HomeOffset") == -1.5
    assert image.read("Plain.HomeMode") == HomeMode.ACTIVE
    assert image.read("Homed.HomeSwitch") is False
