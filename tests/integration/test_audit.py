"""Audit log: accepted and refused writes as JSON lines, over a real socket; rotation."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.pdu import ExceptionResponse

from motion_server import config
from motion_server.safety import ClientInfo, writing_as
from motion_server.safety.audit import AuditLog
from motion_server.tagmap import TagType, build_tagmap
from tests.integration.test_modbus import Tags, start
from tests.modbus_support import SITE, modbus_site


def lines(path: Path) -> list[dict[str, object]]:
    return [json.loads(line) for line in path.read_text("utf-8").splitlines()]


async def test_accepted_and_refused_writes_are_audited_with_client_and_values(
    tmp_path: Path,
) -> None:
    extra = f"""
data_dir = "{tmp_path}"
[audit]
enabled = true
[[modbus.access.rules]]
networks = ["127.0.0.0/8"]
write = ["Instructions"]
"""
    # data_dir is a top-level key: it must come before the first table
    text = extra.split("[audit]")[0] + SITE.format(word_order="big", unit_id=1)
    text += "[audit]" + extra.split("[audit]")[1]
    rt, task, port = await start(config.parse(text, "audit.toml"))
    client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=5)
    assert await client.connect()
    tags = Tags(client, rt.tagmap, 1)
    try:
        await tags.write("MAJ_1.Speed", 25.0)  # accepted: 10.0 -> 25.0
        status = rt.tagmap.tag("MAJ_1.FLAGS")
        rr = await client.write_registers(status.address, [0, 1], device_id=1)  # read-only
        assert isinstance(rr, ExceptionResponse)
        cycles = rt.tagmap.tag("Clock.StepCycles")
        rr = await client.write_registers(cycles.address, [0, 9], device_id=1)  # by rule
        assert isinstance(rr, ExceptionResponse)
    finally:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)
    records = lines(tmp_path / "audit.jsonl")
    accepted = [r for r in records if r["result"] == "accepted"]
    refused = [r for r in records if r["result"] == "refused"]
    assert [(r["tag"], r["old"], r["new"]) for r in accepted] == [("MAJ_1.Speed", 10.0, 25.0)]
    a = accepted[0]
    assert a["protocol"] == "modbus" and a["address"] == "127.0.0.1"
    assert a["user"] == "" and a["role"] == ""  # plain Modbus TCP: no user, no role
    assert isinstance(a["port"], int) and a["port"] > 0
    assert {"time", "cycle", "event", "connection"} <= a.keys()
    assert len(refused) == 2
    assert refused[0]["function_code"] == 16
    assert f"{cycles.address}+2" in str(refused[1]["reason"])
    assert "may not write" in str(refused[1]["reason"])


def test_audit_lines_rotate_by_size(tmp_path: Path) -> None:
    path = tmp_path / "audit.jsonl"
    log = AuditLog(path, max_bytes=2048, backups=2)
    tag = build_tagmap(modbus_site()).tag("MAJ_1.Speed")
    assert tag.type == TagType.REAL
    with writing_as(ClientInfo("opcua", "127.0.0.1", 4840, 1, user="operator")):
        for k in range(200):
            log.accepted(tag, float(k), float(k + 1))
    log.close()
    files = sorted(p.name for p in tmp_path.iterdir())
    assert files == ["audit.jsonl", "audit.jsonl.1", "audit.jsonl.2"]
    for name in files:
        size = (tmp_path / name).stat().st_size
        assert 0 < size <= 2048
        for record in lines(tmp_path / name):
            assert record["user"] == "operator" and record["protocol"] == "opcua"
    newest = lines(path)[-1]
    assert (newest["old"], newest["new"]) == (199.0, 200.0)
