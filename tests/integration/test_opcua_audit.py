"""Refused OPC UA writes are audited whatever their bytes (real sockets), in a file only
its owner reads.

asyncua decodes an OPC UA String that is not UTF-8 with ``surrogateescape`` (each bad
byte becomes a lone surrogate): a refused write to such a NodeId reached the audit log
as a string its UTF-8 file could not take, and the line was lost. The audit log writes
such bytes escaped (``\\xff``) and every line stays one JSON object in valid UTF-8.
"""

from __future__ import annotations

import asyncio
import json
import stat
from pathlib import Path

import pytest
from asyncua import Client, ua

from motion_server import config
from motion_server.safety.audit import AuditLog
from tests.opcua_support import SITE, running

#: a NodeId whose UTF-8 is broken: 0xFF, 0xFE and a lone continuation byte 0x80
BAD_BYTES = b"\xff\xfe\x80"
BAD_ID = "Instructions.MAG_1." + BAD_BYTES.decode("utf-8", "surrogateescape")


def audited_site(data_dir: Path) -> config.SiteMap:
    text = SITE.format(
        data_dir=data_dir / "opcua", anonymous="true", none_endpoint="true", lockout=0.0, users=""
    )
    text = f'data_dir = "{data_dir}"\n' + text + "\n[audit]\nenabled = true\n"
    return config.parse(text, "audited.toml")


def records(path: Path) -> list[dict[str, object]]:
    raw = path.read_bytes()
    return [json.loads(line) for line in raw.decode("utf-8").splitlines()]  # strict UTF-8


async def test_a_refused_write_to_a_node_id_that_is_not_utf8_is_audited(tmp_path: Path) -> None:
    async with running(audited_site(tmp_path)) as rt:
        assert rt.opcua is not None
        client = Client(rt.opcua.endpoint, timeout=5)
        await client.connect()
        try:
            ns = rt.opcua.namespace_index
            value = ua.DataValue(ua.Variant(1.0, ua.VariantType.Float))
            for node_id in (BAD_ID, "Instructions.MAG_1.Ratio"):  # then a tag, refused too
                with pytest.raises(ua.UaStatusCodeError):
                    await client.get_node(ua.NodeId(node_id, ns)).write_value(value)
        finally:
            await client.disconnect()
        await asyncio.sleep(0)
    path = tmp_path / "audit.jsonl"
    refused = [r for r in records(path) if r["result"] == "refused"]
    assert [r.get("tag") for r in refused] == [None, "MAG_1.Ratio"]
    assert refused[0]["node"] == f"ns={ns};s=Instructions.MAG_1.\\xff\\xfe\\x80"
    assert [r["reason"] for r in refused] == ["BadUserAccessDenied"] * 2  # a viewer
    assert stat.S_IMODE(path.stat().st_mode) == 0o600


def test_a_line_from_another_process_with_lone_surrogates_is_written_escaped(
    tmp_path: Path,
) -> None:
    """The supervisor writes the front-ends' lines as it gets them (JSON text)."""
    log = AuditLog(tmp_path / "audit.jsonl")
    log.write_line(json.dumps({"node": "s=" + BAD_ID}, ensure_ascii=False))
    log.write_line(json.dumps({"node": "s=ok"}))
    log.close()
    found = records(tmp_path / "audit.jsonl")
    assert found == [{"node": "s=" + BAD_ID}, {"node": "s=ok"}]  # as JSON escapes


def test_the_audit_file_and_its_rotations_are_private(tmp_path: Path) -> None:
    path = tmp_path / "audit.jsonl"
    path.write_text("")
    path.chmod(0o644)  # an older, readable file is made private too
    log = AuditLog(path, max_bytes=1024, backups=2)
    for i in range(100):
        log.write_line(json.dumps({"n": i, "pad": "x" * 100}))
    log.close()
    files = sorted(tmp_path.glob("audit.jsonl*"))
    assert len(files) == 3
    assert {stat.S_IMODE(f.stat().st_mode) for f in files} == {0o600}
