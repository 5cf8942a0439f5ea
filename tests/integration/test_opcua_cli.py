"""The OPC UA parts of the command line: ``motion-server hash-password`` (standard input
to a hash that verifies, the password never printed or logged) and ``run --opcua-port``.
"""

from __future__ import annotations

import io
import logging
import re
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from motion_server import cli
from motion_server.frontends.opcua_users import parse_hash, verify_password

PASSWORD = "correct horse battery staple"


def test_hash_password_reads_stdin_and_prints_a_hash_that_verifies(
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    caplog: pytest.LogCaptureFixture,
) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO(PASSWORD + "\n"))
    with caplog.at_level(logging.DEBUG):
        assert cli.main(["hash-password"]) == 0
    out, err = capsys.readouterr()
    lines = out.splitlines()
    assert len(lines) == 1
    hashed = lines[0]
    n, r, p, salt, key = parse_hash(hashed)
    assert (n, r, p, len(salt), len(key)) == (2**14, 8, 1, 16, 32)
    assert verify_password(PASSWORD, hashed)
    assert not verify_password(PASSWORD + " ", hashed)  # the newline only was stripped
    for text in (out, err, caplog.text):
        assert "horse" not in text


def test_hash_password_salts_every_hash(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    hashes = []
    for _ in range(2):
        monkeypatch.setattr(sys, "stdin", io.StringIO(PASSWORD + "\n"))
        cli.main(["hash-password"])
        hashes.append(capsys.readouterr().out.strip())
    assert hashes[0] != hashes[1]
    assert all(verify_password(PASSWORD, h) for h in hashes)


def test_hash_password_refuses_an_empty_password(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n"))
    with pytest.raises(SystemExit, match="empty password"):
        cli.main(["hash-password"])


def test_hash_password_from_a_pipe() -> None:
    r = subprocess.run(
        [sys.executable, "-m", "motion_server.cli", "hash-password"],
        input=PASSWORD + "\n",
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert verify_password(PASSWORD, r.stdout.strip())
    assert "horse" not in r.stdout + r.stderr


@pytest.mark.parametrize("port", ["-1", "65536"])
def test_run_refuses_an_opcua_port_out_of_range(port: str) -> None:
    with pytest.raises(SystemExit, match="port"):
        cli.main(["run", "--opcua-port", port, "--no-modbus"])


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def test_run_serves_opcua_on_the_given_port(tmp_path: Path) -> None:
    port = _free_port()
    log = tmp_path / "server.log"
    cmd = [sys.executable, "-m", "motion_server.cli", "run", "--clock", "manual", "--no-modbus"]
    cmd.append("--no-ethernetip")  # the demo's port 44818 may be taken
    with log.open("wb") as f:
        proc = subprocess.Popen(
            [*cmd, "--opcua-port", str(port)],
            cwd=tmp_path,  # the demo's data_dir is relative: the certificate goes here
            stderr=f,
            stdout=subprocess.DEVNULL,
        )
    try:
        pattern = re.compile(r"OPC UA on opc\.tcp://127\.0\.0\.1:(\d+)/")
        deadline = time.monotonic() + 60
        m = None
        while m is None and time.monotonic() < deadline and proc.poll() is None:
            m = pattern.search(log.read_text(errors="replace"))
            if m is None:
                time.sleep(0.1)  # waiting for another process's log, not for simulated time
        assert m is not None, log.read_text()
        assert int(m.group(1)) == port
        with socket.create_connection(("127.0.0.1", port), timeout=5):
            pass
        assert (tmp_path / "opcua-data" / "server-cert.der").is_file()
    finally:
        proc.terminate()
        proc.wait(30)
    assert proc.returncode == 0, log.read_text()
