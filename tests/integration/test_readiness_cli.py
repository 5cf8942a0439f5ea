"""`motion-server run` and readiness: the Modbus port stays closed until the controller
runs (an early client is refused at once, never left with a write that hangs), the ready
file names the ports once every front-end listens and goes away when the server stops,
and with no OPC UA user configured the generated admin logs in with the password from
the data directory."""

from __future__ import annotations

import asyncio
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from asyncua import ua
from pyModbusTCP.client import ModbusClient

from motion_server import config
from motion_server.frontends.opcua_users import hash_password
from motion_server.tagmap import TagType, build_tagmap, decode
from motion_server.testing import MotionServer
from tests.opcua_support import SITE as OPCUA_SITE
from tests.opcua_support import secure_client_at


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _start(
    args: list[str], cwd: Path, env: dict[str, str] | None = None
) -> subprocess.Popen[bytes]:
    return subprocess.Popen(
        [sys.executable, "-m", "motion_server.cli", "run", *args],
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.DEVNULL,
        stderr=(cwd / "server.log").open("ab"),
        env=env,
    )


def _stop(proc: subprocess.Popen[bytes]) -> int:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    return proc.returncode


def _wait_file(path: Path, proc: subprocess.Popen[bytes], log: Path) -> dict[str, object]:
    deadline = time.monotonic() + 180
    while not path.exists():
        assert proc.poll() is None, log.read_text(errors="replace")
        assert time.monotonic() < deadline, log.read_text(errors="replace")
        time.sleep(0.05)  # another process's progress, not simulated time
    info: dict[str, object] = json.loads(path.read_text())
    return info


def test_the_modbus_port_opens_only_once_the_controller_runs(tmp_path: Path) -> None:
    tagmap = build_tagmap(config.load())
    port = _free_port()
    ready_file = tmp_path / "ready.json"
    args = ["--clock", "manual", "--modbus-port", str(port), "--no-opcua", "--no-ethernetip"]
    proc = _start([*args, "--ready-file", str(ready_file)], tmp_path)
    refused = 0
    try:
        deadline = time.monotonic() + 180
        while True:
            assert proc.poll() is None, (tmp_path / "server.log").read_text()
            assert time.monotonic() < deadline, (tmp_path / "server.log").read_text()
            try:
                sock = socket.create_connection(("127.0.0.1", port), timeout=3.0)
            except ConnectionRefusedError:
                refused += 1  # a clear answer, at once
                time.sleep(0.01)
                continue
            sock.close()
            break
        # the scan takes seconds to build and start: the first attempts were refused
        assert refused > 0
        # the first client that gets in finds a running controller, and a Clock.Step is
        # answered (3 s client timeout) once its cycles ran
        client = ModbusClient(host="127.0.0.1", port=port, unit_id=1, timeout=3.0)
        ready = tagmap.tag("Diagnostics.Ready")
        assert client.read_holding_registers(ready.address, 1) == [1 << (ready.bit or 0)]
        steps = tagmap.tag("Clock.StepCycles")
        assert client.write_multiple_registers(steps.address, [0, 5])
        assert client.write_single_register(tagmap.tag("Clock.Step").address, 1)
        cycle = tagmap.tag("Clock.Cycle")
        regs = client.read_holding_registers(cycle.address, 2)
        assert regs is not None and decode(TagType.UDINT, regs) == 5
        client.close()
        # the ready file: once every front-end listens; it names this process and port
        info = _wait_file(ready_file, proc, tmp_path / "server.log")
        assert info["format"] == "motion-server-ready/1"
        assert info["pid"] == proc.pid and info["site"] == "demo"
        assert info["modbus"] == {"host": "127.0.0.1", "port": port, "tls_port": 0}
        assert "opcua" not in info
    finally:
        code = _stop(proc)
    assert code == 0, (tmp_path / "server.log").read_text()
    assert not ready_file.exists()
    assert list(tmp_path.glob(".ready.json.*")) == []


def test_a_ready_file_that_cannot_be_written_stops_the_start(tmp_path: Path) -> None:
    args = ["--clock", "manual", "--modbus-port", "0", "--no-opcua", "--no-ethernetip"]
    proc = _start([*args, "--ready-file", str(tmp_path / "missing" / "ready.json")], tmp_path)
    assert proc.wait(180) == 1
    log = (tmp_path / "server.log").read_text()
    assert "cannot write the ready file" in log and "missing/ready.json" in log
    assert "Traceback" not in log


SITE_NO_USERS = OPCUA_SITE.format(
    data_dir="opcua-data", anonymous="false", none_endpoint="false", lockout=30.0, users=""
)


#: what a refused login answers
REFUSED = {ua.StatusCodes.BadUserAccessDenied, ua.StatusCodes.BadIdentityTokenRejected}


async def _login(endpoint: str, client_dir: Path, user: str, password: str) -> int:
    """Log in, write Clock.StepCycles (admin only); the write's status code value."""
    client = await secure_client_at(endpoint, client_dir, user, password)
    async with client:
        ns = await client.get_namespace_index("urn:motion-server:opcua-test")
        node = client.get_node(ua.NodeId("Clock.StepCycles", ns))
        dv = ua.DataValue(ua.Variant(3, ua.VariantType.UInt32))
        result = await client.uaclient.write_attributes([node.nodeid], [dv], ua.AttributeIds.Value)
        return int(result[0].value)


@pytest.mark.slow
def test_the_generated_admin_logs_in_and_a_users_file_replaces_it(tmp_path: Path) -> None:
    site = tmp_path / "site.toml"
    site.write_text(SITE_NO_USERS)
    work = tmp_path / "work"  # both starts: the same data directory
    server = MotionServer.start(work, site)
    try:
        password = server.opcua_admin_password
        assert password is not None
        assert asyncio.run(_login(server.opcua_endpoint, tmp_path, "admin", password)) == 0
        with pytest.raises(ua.UaStatusCodeError) as refused:
            asyncio.run(_login(server.opcua_endpoint, tmp_path, "admin", password + "x"))
        assert refused.value.code in REFUSED
    finally:
        assert server.stop() == 0, server.log_tail()
    log = server.log()
    assert f"its password is in {work / 'opcua-data' / 'admin-password'}" in log
    assert password not in log
    # a users file of our own: the generated admin is no longer let in
    users_file = tmp_path / "users-secret.toml"
    users_file.write_text(
        f'[[users]]\nname = "op"\nrole = "operator"\n'
        f'password_hash = "{hash_password("own-password", n=2**10)}"\n'
    )
    env = {**os.environ, config.USERS_FILE_ENV: str(users_file)}
    server = MotionServer.start(work, site, env=env)
    try:
        with pytest.raises(ua.UaStatusCodeError) as refused:
            asyncio.run(_login(server.opcua_endpoint, tmp_path, "admin", password))
        assert refused.value.code in REFUSED
        # the operator logs in, and may not touch the clock (admin only)
        status = asyncio.run(_login(server.opcua_endpoint, tmp_path, "op", "own-password"))
        assert status == ua.StatusCodes.BadUserAccessDenied
    finally:
        assert server.stop() == 0, server.log_tail()
    # the generated files stay where they were, unchanged
    assert server.opcua_admin_password == password
