"""The role of plain Modbus TCP clients, over real sockets (issue 24): admin on a map
without users or TLS roles (as before), operator on a map that defines either, more only
when ``[modbus.access] role`` grants it; one line at start says which."""

from __future__ import annotations

import asyncio
import logging
from collections.abc import AsyncIterator, Awaitable, Callable

import pytest
from pymodbus.client import AsyncModbusTcpClient
from pymodbus.pdu import ExceptionResponse

from motion_server.runtime import Runtime
from motion_server.safety.passwords import hash_password
from tests.integration import test_access
from tests.integration.test_modbus import Tags, start

#: one OPC UA user; OPC UA itself stays off (the test site's): defining users is enough
USER = '\n[[opcua.users]]\nname = "op"\nrole = "admin"\npassword_hash = "{h}"\n'


@pytest.fixture
async def serve() -> AsyncIterator[Callable[[str], Awaitable[test_access.Started]]]:
    """``rt, client, tags = await serve(extra_toml)``; everything closed afterwards."""
    opened: list[tuple[Runtime, asyncio.Task[None], AsyncModbusTcpClient]] = []

    async def open_(extra: str) -> test_access.Started:
        rt, task, port = await start(test_access.site_with(extra))
        client = AsyncModbusTcpClient("127.0.0.1", port=port, timeout=2, retries=0)
        await client.connect()
        opened.append((rt, task, client))
        return rt, client, Tags(client, rt.tagmap, 1)

    yield open_
    for rt, task, client in opened:
        client.close()
        rt.request_stop()
        await asyncio.wait_for(task, 10.0)


def with_user(extra: str = "") -> str:
    return USER.format(h=hash_password("secret", n=2**10)) + extra


async def code_of(tags: Tags, name: str, registers: list[int]) -> int:
    """Write raw registers to ``name``: the exception code (0: accepted)."""
    tag = tags.map.tag(name)
    rr = await tags.client.write_registers(tag.address, registers, device_id=1)
    return rr.exception_code if isinstance(rr, ExceptionResponse) else 0


async def test_a_map_without_users_keeps_plain_modbus_admin(serve, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, "motion_server.modbus")
    rt, _, tags = await serve("")
    assert await code_of(tags, "Clock.StepCycles", [0, 3]) == 0
    assert rt.image.read("Clock.StepCycles") == 3
    lines = [r.getMessage() for r in caplog.records if "plain clients" in r.getMessage()]
    assert lines == [
        "Modbus TCP: plain clients have role admin (no users and no TLS roles are defined)"
    ]


async def test_users_make_plain_modbus_an_operator(serve, caplog) -> None:  # type: ignore[no-untyped-def]
    caplog.set_level(logging.INFO, "motion_server.modbus")
    rt, _, tags = await serve(with_user())
    before = rt.image.read("Clock.StepCycles")
    # the Clock tags (mode, step, snapshots, communication faults) are refused: 02
    assert await code_of(tags, "Clock.CommFault", [2]) == 2
    assert await code_of(tags, "Clock.Mode", [3]) == 2
    assert await code_of(tags, "Clock.StepCycles", [0, 3]) == 2
    assert rt.image.read("Clock.StepCycles") == before
    assert rt.image.read("Clock.CommFault") == 0
    restore = tags.map.tag("Clock.SnapshotRestore")  # a bit: FC22 sets it alone
    bit = 1 << (restore.bit or 0)
    rr = await tags.client.mask_write_register(
        address=restore.address, and_mask=~bit & 0xFFFF, or_mask=bit, device_id=1
    )
    assert isinstance(rr, ExceptionResponse) and rr.exception_code == 2
    # an operator still runs the machine: operands and triggers
    assert await code_of(tags, "MAJ_1.Speed", [0x41C8, 0]) == 0  # 25.0
    assert rt.image.read("MAJ_1.Speed") == 25.0
    warned = [r for r in caplog.records if "plain clients" in r.getMessage()]
    assert len(warned) == 1 and warned[0].levelno == logging.WARNING
    assert "role operator" in warned[0].getMessage()
    assert "[modbus.access] role" in warned[0].getMessage()


async def test_tls_roles_make_plain_modbus_an_operator(serve, tmp_path) -> None:  # type: ignore[no-untyped-def]
    from tests.integration.test_modbus_tls import Authority

    pki = Authority(tmp_path / "pki", "Site CA")
    server = pki.issue("motion-server", server=True)
    tls = (
        f'\n[modbus.tls]\nenabled = true\nport = 0\nca_file = "{pki.pem}"\n'
        f'cert_file = "{server.cert}"\nkey_file = "{server.key}"\n'
    )
    _rt, _, tags = await serve(tls)
    assert await code_of(tags, "Clock.CommFault", [2]) == 2
    assert await code_of(tags, "MAJ_1.Speed", [0x41C8, 0]) == 0


@pytest.mark.parametrize(("role", "clock", "operand"), [("admin", 0, 0), ("viewer", 2, 2)])
async def test_modbus_access_role_sets_the_plain_role(  # type: ignore[no-untyped-def]
    serve, caplog, role: str, clock: int, operand: int
) -> None:
    caplog.set_level(logging.INFO, "motion_server.modbus")
    _rt, _, tags = await serve(with_user(f'\n[modbus.access]\nrole = "{role}"\n'))
    assert await code_of(tags, "Clock.StepCycles", [0, 3]) == clock
    assert await code_of(tags, "MAJ_1.Speed", [0x41C8, 0]) == operand
    said = [r for r in caplog.records if "plain clients" in r.getMessage()]
    assert len(said) == 1 and said[0].levelno == logging.WARNING
    assert f"role {role} ([modbus.access] role" in said[0].getMessage()


def test_the_run_option_sets_the_plain_role() -> None:
    from motion_server import cli, config

    site = config.parse(
        test_access.SITE.format(word_order="big", unit_id=1) + with_user(), "r.toml"
    )
    args = cli.build_parser().parse_args(["run", "--modbus-role", "admin"])
    assert cli.site_for_run(site, args).modbus.access.role == "admin"
    assert site.modbus.access.role is None  # the map itself is unchanged
