"""The first OPC UA user (``safety/first_user.py``): created once when no user is
configured, kept private, reused by later starts, never used beside configured users."""

from __future__ import annotations

import logging
import stat
from pathlib import Path

import pytest

from motion_server import config
from motion_server.frontends.opcua_users import hash_password, verify_password
from motion_server.safety import first_user
from motion_server.safety.first_user import FirstUserError, ensure_user


def _cfg(data_dir: Path) -> config.OpcUaSection:
    return config.OpcUaSection(data_dir=str(data_dir))


def test_configured_users_are_kept_and_nothing_is_written(tmp_path: Path) -> None:
    mine = config.OpcUaUser(name="op", role="operator", password_hash=hash_password("x", n=2**10))
    assert ensure_user(_cfg(tmp_path / "data"), [mine]) == [mine]
    assert not (tmp_path / "data").exists()


def test_no_user_creates_a_private_admin_and_logs_where_not_what(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    data = tmp_path / "data"
    with caplog.at_level(logging.INFO, logger="motion_server.first_user"):
        users = ensure_user(_cfg(data), [])
    assert [(u.name, u.role) for u in users] == [("admin", "admin")]
    password_file = data / "admin-password"
    users_file = data / "users.toml"
    password = password_file.read_text().strip()
    assert len(password) == 24  # 18 random bytes, urlsafe base64
    assert verify_password(password, users[0].password_hash)
    for path in (password_file, users_file):
        assert stat.S_IMODE(path.stat().st_mode) == 0o600, path
    # the users file is a users file: the hash, never the password
    assert config.load_users_file(users_file) == users
    assert password not in users_file.read_text()
    # one line, naming the password file, never the password
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 1 and str(password_file.resolve()) in lines[0]
    assert password not in caplog.text
    assert not list(data.glob(".*.tmp"))  # written by rename: no temporary file left


def test_a_later_start_reuses_the_generated_admin(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    data = tmp_path / "data"
    first = ensure_user(_cfg(data), [])
    password = (data / "admin-password").read_text()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="motion_server.first_user"):
        again = ensure_user(_cfg(data), [])
    assert again == first
    assert (data / "admin-password").read_text() == password
    assert "generated at the first start" in caplog.text and "created" not in caplog.text


def test_a_configured_user_wins_over_the_generated_one(tmp_path: Path) -> None:
    data = tmp_path / "data"
    ensure_user(_cfg(data), [])
    mine = config.OpcUaUser(name="op", role="operator", password_hash=hash_password("x", n=2**10))
    assert ensure_user(_cfg(data), [mine]) == [mine]


def test_a_lost_password_file_is_said(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    data = tmp_path / "data"
    ensure_user(_cfg(data), [])
    (data / "admin-password").unlink()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="motion_server.first_user"):
        ensure_user(_cfg(data), [])
    assert "admin-password is gone: delete" in caplog.text


def test_a_broken_generated_file_is_one_line_naming_it(tmp_path: Path) -> None:
    data = tmp_path / "data"
    data.mkdir()
    (data / "users.toml").write_text('[[users]]\nname = "admin"\npassword_hash = "nope"\n')
    with pytest.raises(FirstUserError) as err:
        ensure_user(_cfg(data), [])
    message = str(err.value)
    assert "users.toml:3" in message and "delete it" in message and "\n" not in message


def test_a_data_directory_that_cannot_be_made_is_one_line(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with pytest.raises(FirstUserError) as err:
        ensure_user(_cfg(blocker / "data"), [])
    message = str(err.value)
    assert "cannot be created in" in message and "MOTION_SERVER_USERS_FILE" in message
    assert "\n" not in message


def test_the_password_comes_from_the_system_random_source(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls: list[int] = []

    def token(n: int) -> str:
        calls.append(n)
        return "A" * 24

    monkeypatch.setattr(first_user.secrets, "token_urlsafe", token)
    ensure_user(_cfg(tmp_path), [])
    assert calls == [first_user.PASSWORD_BYTES]
    assert (tmp_path / "admin-password").read_text() == "A" * 24 + "\n"
