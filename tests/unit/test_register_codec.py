"""One register codec (issue 24): the server's tag map, the clients and the container's
health check encode through ``motion_clients.codec``, which agrees with pymodbus'
``convert_to_registers`` / ``convert_from_registers`` wherever those define a value."""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import pytest
from pymodbus.client.mixin import ModbusClientMixin

from motion_clients import codec
from motion_clients import tagmap as client_tagmap
from motion_server.instructions.schema import TagType
from motion_server.tagmap import codec as server_codec
from motion_server.tagmap.model import WordOrder

ROOT = Path(__file__).resolve().parents[2]
DT = ModbusClientMixin.DATATYPE
PYMODBUS = {
    "SINT": DT.INT16,
    "INT": DT.INT16,
    "UINT": DT.UINT16,
    "DINT": DT.INT32,
    "UDINT": DT.UINT32,
    "REAL": DT.FLOAT32,
    "LREAL": DT.FLOAT64,
}
SAMPLES: dict[str, list[float]] = {
    "SINT": [-128, -1, 0, 1, 127],
    "INT": [-32768, -1, 0, 1, 32767],
    "UINT": [0, 1, 0x8000, 65535],
    "DINT": [-(2**31), -65536, -1, 0, 1, 65536, 2**31 - 1],
    "UDINT": [0, 1, 65535, 65536, 2**32 - 1],
    "REAL": [0.0, -0.0, 10.0, -2.5, 1e-40, 3.4028234663852886e38, math.inf],
    "LREAL": [0.0, 10.0, -1e300, 5e-324, 2.0**53 + 2, -math.inf],
}


@pytest.mark.parametrize("order", ["big", "little"])
@pytest.mark.parametrize("type_name", sorted(PYMODBUS))
def test_the_codec_agrees_with_pymodbus(type_name: str, order: str) -> None:
    for value in SAMPLES[type_name]:
        ours = codec.encode(type_name, value, order)
        theirs = ModbusClientMixin.convert_to_registers(value, PYMODBUS[type_name], order)  # type: ignore[arg-type]
        assert ours == theirs, (type_name, value, order)
        back = ModbusClientMixin.convert_from_registers(ours, PYMODBUS[type_name], order)  # type: ignore[arg-type]
        assert codec.decode(type_name, ours, order) == back


def test_where_pymodbus_raises_the_codec_defines_a_value() -> None:
    # 1e39 is beyond binary32: infinity of its sign, so the server can publish what it holds
    assert codec.encode("REAL", 1e39) == [0x7F80, 0x0000]
    assert codec.encode("REAL", -1e39) == [0xFF80, 0x0000]
    # an integer beyond its type keeps its low bits (callers judge ranges first)
    assert codec.encode("DINT", 2**32 + 5) == [0x0000, 0x0005]
    assert codec.encode("BOOL", True) == [1] and codec.decode("BOOL", [1]) is True


def test_server_clients_and_health_check_use_the_shared_codec(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    calls: list[str] = []
    real = codec.encoder, codec.decoder

    def spy_encoder(type_name: str, word_order: str = "big"):  # type: ignore[no-untyped-def]
        calls.append(f"enc {type_name}")
        return real[0](type_name, word_order)

    def spy_decoder(type_name: str, word_order: str = "big"):  # type: ignore[no-untyped-def]
        calls.append(f"dec {type_name}")
        return real[1](type_name, word_order)

    monkeypatch.setattr(codec, "encoder", spy_encoder)
    monkeypatch.setattr(codec, "decoder", spy_decoder)
    assert server_codec.encode(TagType.REAL, 10.0, WordOrder.LITTLE) == [0x0000, 0x4120]
    assert server_codec.decode(TagType.DINT, [0, 7]) == 7
    tag = client_tagmap.MapTag("X.Y", "REAL", "read_write", 0, 2, "X.Y")
    assert client_tagmap.encode(tag, 10.0) == [0x4120, 0x0000]
    assert client_tagmap.decode(tag, [0x4120, 0x0000]) == 10.0
    spec = importlib.util.spec_from_file_location("hb", ROOT / "container" / "heartbeat.py")
    assert spec is not None and spec.loader is not None
    hb = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hb)
    assert hb.encode(5, "UDINT", "little") == [5, 0]
    assert hb.decode([0, 5], "UDINT", "big") == 5
    assert calls == [
        "enc REAL",
        "dec DINT",
        "enc REAL",
        "dec REAL",
        "enc UDINT",
        "dec UDINT",
    ]


def test_the_sint_range_is_still_checked_by_the_server() -> None:
    with pytest.raises(server_codec.RegisterValueError):
        server_codec.decode(TagType.SINT, [200])
    assert server_codec.decode(TagType.SINT, [0xFF80]) == -128


def test_importing_the_codec_loads_no_protocol_library() -> None:
    probe = (
        "import sys, motion_clients.codec\n"
        "print([m for m in sys.modules if m.split('.')[0] in ('pymodbus', 'asyncua')])"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
