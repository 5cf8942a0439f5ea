"""Site map overrides from the environment: MOTION_SERVER_MAP and
MOTION_SERVER_<SECTION>_<FIELD> (what the container image relies on)."""

from __future__ import annotations

from pathlib import Path

import pytest

from motion_server import config

SMALL_MAP = """
[modbus]
host = "127.0.0.1"
port = 5020

[[groups]]
name = "G"
axes = ["A"]

[[axes]]
name = "A"
type = "virtual"
"""


@pytest.fixture
def small_map(tmp_path: Path) -> Path:
    path = tmp_path / "small.toml"
    path.write_text(SMALL_MAP)
    return path


def test_no_variables_leave_the_map_as_written(small_map: Path) -> None:
    site = config.load(small_map, environ={})
    assert site.modbus.host == "127.0.0.1"
    assert site.modbus.port == 5020
    assert site == config.parse(SMALL_MAP, str(small_map))


def test_bind_address_and_port_from_the_environment(small_map: Path) -> None:
    env = {"MOTION_SERVER_MODBUS_HOST": "0.0.0.0", "MOTION_SERVER_MODBUS_PORT": "15020"}
    site = config.load(small_map, environ=env)
    assert site.modbus.host == "0.0.0.0"
    assert site.modbus.port == 15020
    # everything else is untouched
    assert site.axes == config.load(small_map, environ={}).axes
    assert site.source == str(small_map)


def test_controller_settings_from_the_environment() -> None:
    env = {
        "MOTION_SERVER_CONTROLLER_CLOCK": "manual",
        "MOTION_SERVER_CONTROLLER_STATUS_LOG_INTERVAL": "1.5",
    }
    site = config.load(None, environ=env)
    assert site.controller.clock == "manual"
    assert site.controller.status_log_interval == 1.5


def test_other_motion_server_variables_are_not_settings(small_map: Path) -> None:
    env = {"MOTION_SERVER_USERS_FILE": "/run/secrets/users", "MOTION_SERVER_FOO_BAR": "1"}
    assert config.load(small_map, environ=env) == config.load(small_map, environ={})


@pytest.mark.parametrize(
    ("var", "value", "expected"),
    [
        ("MOTION_SERVER_MODBUS_PORT", "70000", "less than or equal to 65535"),
        ("MOTION_SERVER_MODBUS_PORT", "five", "valid integer"),
        ("MOTION_SERVER_CONTROLLER_CLOCK", "sometimes", "'realtime', 'scaled', 'manual' or 'fast'"),
        ("MOTION_SERVER_MODBUS_WORD_ORDER", "middle", "'big' or 'little'"),
    ],
)
def test_invalid_values_name_the_variable(
    small_map: Path, var: str, value: str, expected: str
) -> None:
    with pytest.raises(config.SiteMapError) as err:
        config.load(small_map, environ={var: value})
    message = str(err.value)
    assert f"{small_map}: environment {var}: " in message
    assert expected in message


def test_map_file_from_the_environment(small_map: Path) -> None:
    site = config.load(None, environ={"MOTION_SERVER_MAP": str(small_map)})
    assert site.source == str(small_map)
    assert [a.name for a in site.axes] == ["A"]


def test_an_explicit_path_wins_over_the_environment(small_map: Path) -> None:
    site = config.load(small_map, environ={"MOTION_SERVER_MAP": "/nonexistent.toml"})
    assert site.source == str(small_map)


def test_unreadable_map_from_the_environment_is_a_site_map_error(tmp_path: Path) -> None:
    missing = tmp_path / "missing.toml"
    with pytest.raises(config.SiteMapError, match=r"missing\.toml: cannot read site map"):
        config.load(None, environ={"MOTION_SERVER_MAP": str(missing)})


def test_process_environment_is_the_default(
    small_map: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MOTION_SERVER_MAP", str(small_map))
    monkeypatch.setenv("MOTION_SERVER_MODBUS_HOST", "0.0.0.0")
    site = config.load()
    assert site.source == str(small_map)
    assert site.modbus.host == "0.0.0.0"


def test_empty_map_variable_means_the_demo_map() -> None:
    site = config.load(None, environ={"MOTION_SERVER_MAP": ""})
    assert site.source == "<embedded demo.toml>"


def test_a_section_the_map_does_not_write_can_be_set() -> None:
    # the demo map has no [modbus] table: the variable creates it
    site = config.load(None, environ={"MOTION_SERVER_MODBUS_PORT": "0"})
    assert site.modbus.port == 0
    assert site.modbus.host == "127.0.0.1"


def test_transport_limits_must_let_the_chunks_carry_the_largest_message() -> None:
    """OPC UA: max_chunk_size × max_chunk_count >= max_message_size, else a peer (node-opcua)
    warns that the chunks cannot carry the message; the defaults meet it exactly:
    65536 × 64 = 4 MiB."""
    defaults = config.OpcUaSection()
    assert defaults.max_chunk_size * defaults.max_chunk_count == defaults.max_message_size
    with pytest.raises(ValueError, match="raise max_chunk_count to 65"):
        config.OpcUaSection(max_chunk_size=65535, max_chunk_count=64)
    # asyncua clients ask for a one-hour session (3,600,000 ms): the maximum allows it
    assert defaults.max_session_timeout_s >= 3600.0


def test_a_map_without_data_dir_never_uses_the_working_directory() -> None:
    """The data directory of a map that sets none: $MOTION_SERVER_DATA_DIR, else the
    user's state directory (XDG), per site; a map's own data_dir is kept."""
    text = '[site]\nname = "line1"\n[[axes]]\nname = "A"\ntype = "virtual"\n' + (
        '[[groups]]\nname = "G"\naxes = ["A"]\n'
    )
    assert config.parse(text, environ={"HOME": "/h"}).data_dir == (
        "/h/.local/state/motion-server/line1"
    )
    env = {"HOME": "/h", "XDG_STATE_HOME": "/state"}
    assert config.parse(text, environ=env).data_dir == "/state/motion-server/line1"
    env = {"HOME": "/h", "XDG_STATE_HOME": "relative"}  # ignored, as XDG says
    assert config.parse(text, environ=env).data_dir == "/h/.local/state/motion-server/line1"
    env = {"HOME": "/h", "MOTION_SERVER_DATA_DIR": "/var/lib/ms"}
    assert config.parse(text, environ=env).data_dir == "/var/lib/ms"
    assert config.loading.unknown_variables(env) == []
    assert config.parse('data_dir = "here"\n' + text, environ=env).data_dir == "here"
