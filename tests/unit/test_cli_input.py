"""The command line and the ``MOTION_SERVER_*`` variables: one line, never a traceback.

Every case here froze the clock silently, raised a traceback, or (``check /dev/zero``)
never returned. Malformed options exit with status 2, everything else with status 1.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest

from motion_server import cli

SITE = """
[modbus]
port = 0

[opcua]
port = 0
data_dir = "{data}"

[[axes]]
name = "A"
type = "virtual"

[[groups]]
name = "G"
axes = ["A"]
"""


@pytest.fixture
def site(tmp_path: Path) -> Path:
    path = tmp_path / "site.toml"
    path.write_text(SITE.format(data=tmp_path / "opcua"))
    return path


def refused(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int | str, str]:
    """Run the command line in-process: (exit code or message, the one line it printed)."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    err = capsys.readouterr().err
    code = exc.value.code
    line = code if isinstance(code, str) else err.rstrip("\n")
    assert line and "\n" not in line and "Traceback" not in line, line
    assert code is not None
    return code, line


@pytest.mark.parametrize("scale", ["-5", "0", "nan", "inf", "1e-300", "-inf", "101", "fast"])
@pytest.mark.parametrize("command", ["run", "check"])
def test_scale_outside_its_range(
    command: str, scale: str, site: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, line = refused([command, str(site), f"--scale={scale}"], capsys)
    assert code == 2
    assert line.startswith(f"motion-server {command}: error: argument --scale: '{scale}': ")


def test_scale_from_the_environment(
    site: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MOTION_SERVER_CONTROLLER_SCALE", "nan")
    code, line = refused(["check", str(site)], capsys)
    assert code == line
    assert line.startswith(f"motion-server: {site}: environment MOTION_SERVER_CONTROLLER_SCALE: ")


@pytest.mark.parametrize(
    ("option", "value"),
    [("--modbus-port", "70000"), ("--opcua-port", "-1"), ("--modbus-host", "example.com")],
)
def test_bind_options_are_checked_like_the_map(
    option: str, value: str, site: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, line = refused(["check", str(site), option, value], capsys)
    assert code == 2 and f"argument {option}: '{value}': " in line


def test_log_level_bogus(site: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, line = refused(["--log-level", "BOGUS", "check", str(site)], capsys)
    assert code == 2
    assert "argument --log-level: 'BOGUS': expected one of DEBUG, INFO, WARNING" in line


def test_log_level_in_lower_case_is_fine(site: Path) -> None:
    assert cli.main(["--log-level", "warning", "check", str(site)]) == 0


def test_map_output_into_a_missing_directory(
    tmp_path: Path, site: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = tmp_path / "missing" / "map.json"
    code, _ = refused(["map", str(site), "-o", str(target)], capsys)
    assert code == f"motion-server: cannot write {target}: No such file or directory"


def test_map_output_onto_a_directory(
    tmp_path: Path, site: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, _ = refused(["map", str(site), "-o", str(tmp_path)], capsys)
    assert code == f"motion-server: cannot write {tmp_path}: Is a directory"


def run_cli(*args: str, stdin: bytes = b"", env: dict[str, str] | None = None) -> tuple[int, str]:
    """A real process: exit status and standard error."""
    r = subprocess.run(
        [sys.executable, "-m", "motion_server.cli", *args],
        input=stdin,
        capture_output=True,
        timeout=60,
        env={**os.environ, **(env or {})},
    )
    return r.returncode, r.stderr.decode("utf-8", "replace")


def test_hash_password_from_input_that_is_not_utf8() -> None:
    status, err = run_cli("hash-password", stdin=b"\xff\xfepassword\n")
    assert status == 1
    assert err == "motion-server: the password on standard input is not UTF-8\n"


def test_hash_password_of_endless_input_is_refused() -> None:
    status, err = run_cli("hash-password", stdin=b"x" * 100_000)
    assert status == 1 and err == "motion-server: a password is at most 4096 bytes\n"


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/null"])
def test_check_of_a_device_is_refused_at_once(device: str) -> None:
    status, err = run_cli("check", device)
    assert status == 1
    assert err == f"motion-server: {device}: cannot read site map: not a regular file\n"


def test_check_of_a_map_that_is_not_utf8(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "latin1.toml"
    path.write_bytes(b'[site]\nname = "caf\xe9"\n')
    code, _ = refused(["check", str(path)], capsys)
    assert code == f"motion-server: {path}:2: site map is not UTF-8 text"


def test_a_misspelt_variable_is_named_with_a_suggestion(
    site: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MOTION_SERVER_MODBUS_PROT", "5021")
    monkeypatch.setenv("MOTION_SERVER_NOTHING_LIKE_IT", "1")
    with caplog.at_level(logging.WARNING, logger="motion_server.config"):
        assert cli.main(["check", str(site)]) == 0
    warnings = [r.getMessage() for r in caplog.records if r.name == "motion_server.config"]
    assert warnings == [
        "environment MOTION_SERVER_MODBUS_PROT is not a motion-server setting; ignored "
        "(did you mean MOTION_SERVER_MODBUS_PORT?)",
        "environment MOTION_SERVER_NOTHING_LIKE_IT is not a motion-server setting; ignored",
    ]


def test_the_variables_the_server_reads_give_no_warning(
    site: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MOTION_SERVER_MODBUS_PORT", "0")
    monkeypatch.setenv("MOTION_SERVER_MAP", str(site))
    with caplog.at_level(logging.WARNING, logger="motion_server.config"):
        assert cli.main(["check"]) == 0
    assert [r for r in caplog.records if r.name == "motion_server.config"] == []


def _users(tmp_path: Path, name: str, content: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(content)
    return path


@pytest.mark.parametrize(
    ("make", "reason"),
    [
        (lambda d: d / "missing.toml", "cannot read users file: No such file or directory"),
        (lambda d: d, "cannot read users file: not a regular file"),
        (lambda d: Path("/dev/zero"), "cannot read users file: not a regular file"),
        (lambda d: _users(d, "bad.toml", b"[[users]\n"), "invalid TOML"),
        (lambda d: _users(d, "latin1.toml", b"# caf\xe9\n"), "users file is not UTF-8 text"),
        (
            lambda d: _users(d, "plain.toml", b'[[users]]\nname = "x"\npassword_hash = "pw"\n'),
            "users.0.password_hash: not a password hash",
        ),
        (
            lambda d: _users(
                d,
                "costly.toml",
                b'[[users]]\nname = "x"\n'
                b'password_hash = "scrypt$1048576$8$1$c2FsdHNhbHQ=$a2V5a2V5a2V5a2V5a2V5a2V5"\n',
            ),
            "users.0.password_hash: unusable password hash: scrypt cost",
        ),
    ],
)
def test_check_with_a_bad_users_file(
    tmp_path: Path,
    site: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    make,  # type: ignore[no-untyped-def]
    reason: str,
) -> None:
    users = make(tmp_path)
    monkeypatch.setenv("MOTION_SERVER_USERS_FILE", str(users))
    code, _ = refused(["check", str(site)], capsys)
    assert isinstance(code, str) and code.startswith(f"motion-server: {users}")
    assert reason in code and "a2V5" not in code


def test_hash_password_of_the_longest_password() -> None:
    status, err = run_cli("hash-password", stdin=b"x" * 4096 + b"\r\n")
    assert status == 0, err
