"""The client library over OPC UA: the very calls of the Modbus tests, on the secure
endpoint (Basic256Sha256, SignAndEncrypt, user name and password).

Kinematics: a jog at 10 mm/s with 100 mm/s² covers 0.5 mm of ramp in 0.1 s (50 cycles)
and 1.5 mm after 100 cycles (0.5 + 10 · 0.1).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import pytest

from motion_clients import ClientError, ClientMap, MotionClient
from motion_server import config
from motion_server.kernel.errors import ERROR_TEXT, ErrorCode
from tests.clients_support import BENCH, BenchServer, client_map, manual_site


@pytest.fixture(scope="module")
def bench(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[int, ClientMap, Path]]:
    tmp = tmp_path_factory.mktemp("opcua")
    site = manual_site(config.load(BENCH), opcua={"data_dir": str(tmp / "data")})
    with BenchServer(site) as srv:
        assert srv.runtime is not None and srv.runtime.opcua is not None
        yield srv.runtime.opcua.port, client_map(site), tmp / "client"


def connect(bench: tuple[int, ClientMap, Path], **opts: object) -> MotionClient:
    port, m, cert_dir = bench
    creds = {"user": "bench", "password": "bench-only", **opts}
    return MotionClient.connect(m, "opcua", port=port, cert_dir=cert_dir, **creds)


async def test_same_calls_over_opcua(bench: tuple[int, ClientMap, Path]) -> None:
    async with connect(bench) as mc:
        assert await mc.clock_mode() == "MANUAL"
        await mc.trigger("CleanStart", until=("PC",))
        assert (await mc.trigger("MSO_1", Axis=1)).ok
        start = float(await mc.read("Master.CommandPosition"))
        jog = await mc.trigger(
            "Jog_Master", Speed=10.0, AccelRate=100.0, DecelRate=100.0, SpeedUnits=0, AccelUnits=0
        )
        assert (jog.ok, jog.flag, jog.cycles) == (True, "DN", 1)
        await mc.step(99)
        pos = float(await mc.read("Master.CommandPosition"))
        assert pos - start == pytest.approx(1.5, abs=1e-9)
        assert await mc.read("Master.CommandVelocity") == pytest.approx(10.0, abs=1e-9)
        assert await mc.read("Jog_Master.IP") is True
        # ERR 13 with EXERR and its meaning, as over Modbus; MAJ's operands: Axis 0,
        # MotionControl 1, Direction 2, Speed 3, SpeedUnits 4, AccelRate 5
        bad = await mc.trigger("MAJ_1", Axis=1, Speed=10.0, AccelRate=-1.0)
        assert (bad.ok, bad.code, bad.exerr) == (False, 13, 5)
        assert bad.meaning == ERROR_TEXT[ErrorCode.PARAMETER_OUT_OF_RANGE]
        await mc.write("MAG_1.Direction", "reverse")
        assert await mc.read("MAG_1.Direction") == 2
        with pytest.raises(ClientError, match="BadOutOfRange"):
            await mc.write("Clock.Mode", 7)


async def test_wrong_password_is_a_clear_connection_error(
    bench: tuple[int, ClientMap, Path],
) -> None:
    with pytest.raises(ClientError, match="cannot connect to OPC UA"):
        async with connect(bench, password="guess"):
            pass


async def test_a_wrong_password_is_one_line_of_ours_without_asyncuas_dump(
    bench: tuple[int, ClientMap, Path], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING)
    port = bench[0]
    with pytest.raises(ClientError) as exc:
        async with connect(bench, password="guess"):
            pass
    assert str(exc.value) == (
        f"cannot connect to OPC UA opc.tcp://127.0.0.1:{port}/: user 'bench' refused "
        "(BadUserAccessDenied): a wrong user name or password, or this address is locked "
        "out for a while after repeated failures"
    )
    leaked = [r.getMessage() for r in caplog.records if r.name.startswith("asyncua.client")]
    assert leaked == []


async def test_a_read_of_more_tags_than_the_servers_limit_is_split(
    tmp_path_factory: pytest.TempPathFactory,
) -> None:
    """The server answers a Read of more than MaxNodesPerRead nodes BadTooManyOperations;
    the client reads that limit from the server and splits its reads by it."""
    tmp = tmp_path_factory.mktemp("opcua-limit")
    opcua = {"data_dir": str(tmp / "data"), "max_nodes_per_read": 7}
    site = manual_site(config.load(BENCH), opcua=opcua)
    m = client_map(site)
    names = [t.name for t in m][:30]
    assert len(names) == 30 > 7
    with BenchServer(site) as srv:
        assert srv.runtime is not None and srv.runtime.opcua is not None
        port = srv.runtime.opcua.port
        creds = {"user": "bench", "password": "bench-only"}
        async with MotionClient.connect(m, "opcua", port=port, cert_dir=tmp / "c", **creds) as mc:
            together = await mc.read_many(names)
            one_by_one = [await mc.read(n) for n in names]
    assert list(together.values()) == one_by_one  # manual clock: nothing moved in between


def test_a_user_name_without_security_is_refused_before_connecting(
    bench: tuple[int, ClientMap, Path],
) -> None:
    with pytest.raises(ClientError, match="needs security Basic256Sha256"):
        connect(bench, security="None")
