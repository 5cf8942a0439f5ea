"""Interop: mbpoll (a C Modbus master from Debian, installed by `make test` when missing)
drives the server over TCP. The same jog as elsewhere: 10 mm/s reached at 100 mm/s²
after 50 cycles (0.5 mm), 1.5 mm after 100 cycles."""

from __future__ import annotations

import re
import shutil
import subprocess
from collections.abc import Iterator

import pytest

from motion_server.tagmap import TagMap, TagType, decode
from tests.modbus_support import ServerThread, modbus_site

pytestmark = pytest.mark.skipif(shutil.which("mbpoll") is None, reason="mbpoll is not installed")

LINE = re.compile(r"^\[(\d+)\]:\s+(\S+)$", re.M)


class MbPoll:
    def __init__(self, port: int, tagmap: TagMap) -> None:
        self.port = port
        self.map = tagmap

    def run(
        self, ref: int, *args: str, values: tuple[str, ...] = ()
    ) -> subprocess.CompletedProcess[str]:
        cmd = ["mbpoll", "-m", "tcp", "-a", "1", "-p", str(self.port), "-0", "-1", "-o", "5"]
        cmd += ["-r", str(ref), *args, "127.0.0.1"]
        if values:
            cmd += ["--", *values]  # mbpoll's separator for negative values
        return subprocess.run(cmd, capture_output=True, text=True, timeout=30)

    def read_regs(self, address: int, count: int) -> list[int]:
        r = self.run(address, "-c", str(count), "-t", "4:hex")
        assert r.returncode == 0, r.stderr
        return [int(v, 16) for _, v in LINE.findall(r.stdout)]

    def read(self, name: str) -> float | int | bool:
        tag = self.map.tag(name)
        regs = self.read_regs(tag.address, tag.count)
        if tag.type == TagType.BOOL:
            return bool(regs[0] >> (tag.bit or 0) & 1)
        return decode(tag.type, regs, self.map.word_order)

    def write(self, name: str, value: str) -> None:
        tag = self.map.tag(name)
        kind = {
            TagType.REAL: ["-t", "4:float", "-B"],
            TagType.DINT: ["-t", "4:int", "-B"],
            TagType.UDINT: ["-t", "4:int", "-B"],
        }
        r = self.run(tag.address, *kind.get(tag.type, ["-t", "4"]), values=(value,))
        assert r.returncode == 0, r.stderr

    def step(self, cycles: int) -> None:
        self.write("Clock.StepCycles", str(cycles))
        self.write("Clock.Step", "0")
        self.write("Clock.Step", "1")

    def trigger(self, instance: str) -> None:
        self.write(f"{instance}.Execute", "0")
        self.write(f"{instance}.Execute", "1")


@pytest.fixture
def mbpoll() -> Iterator[MbPoll]:
    with ServerThread(modbus_site()) as srv:
        assert srv.runtime is not None
        yield MbPoll(srv.port, srv.runtime.tagmap)


def test_jog_the_master_with_mbpoll(mbpoll: MbPoll) -> None:
    mbpoll.write("MSO_1.Axis", "1")
    mbpoll.trigger("MSO_1")
    mbpoll.step(1)
    assert mbpoll.read("MSO_1.DN") is True
    mbpoll.write("MAJ_1.Axis", "1")
    mbpoll.write("MAJ_1.Speed", "10")
    mbpoll.write("MAJ_1.AccelRate", "100")
    mbpoll.trigger("MAJ_1")
    mbpoll.step(1)
    assert (mbpoll.read("MAJ_1.DN"), mbpoll.read("MAJ_1.IP")) == (True, True)
    mbpoll.step(99)
    assert mbpoll.read("Axis1.CommandPosition") == pytest.approx(1.5, abs=1e-9)


def test_out_of_range_and_exceptions_with_mbpoll(mbpoll: MbPoll) -> None:
    mbpoll.write("MSO_1.Axis", "1")
    mbpoll.trigger("MSO_1")
    mbpoll.step(1)
    mbpoll.write("MAJ_1.Axis", "1")
    mbpoll.write("MAJ_1.Speed", "-1")  # Speed must be >= 0: operand 3 of MAJ
    mbpoll.trigger("MAJ_1")
    mbpoll.step(1)
    assert (mbpoll.read("MAJ_1.ER"), mbpoll.read("MAJ_1.ERR"), mbpoll.read("MAJ_1.EXERR")) == (
        True,
        13,
        3,
    )
    r = mbpoll.run(4990, "-c", "20")
    assert r.returncode != 0 and "Illegal data address" in r.stderr
    r = mbpoll.run(mbpoll.map.tag("MAJ_1.ERR").address, values=("0",))
    assert r.returncode != 0 and "Illegal data address" in r.stderr
    r = mbpoll.run(mbpoll.map.tag("Clock.Mode").address, values=("9",))
    assert r.returncode != 0 and "Illegal data value" in r.stderr


def test_a_panel_without_lreal_reads_the_real_mirror_with_mbpoll() -> None:
    """``[modbus] real_mirrors``: mbpoll reads float32 values only (``-t 4:float``, ``-B``:
    the most significant word first, our default word order). The jog above ends at
    1.5 mm and 10 mm/s, both exact in float32."""
    site = modbus_site()
    site = site.model_copy(update={"modbus": site.modbus.model_copy(update={"real_mirrors": True})})
    with ServerThread(site) as srv:
        assert srv.runtime is not None
        mb = MbPoll(srv.port, srv.runtime.tagmap)
        mb.write("MSO_1.Axis", "1")
        mb.trigger("MSO_1")
        mb.step(1)
        mb.write("MAJ_1.Axis", "1")
        mb.write("MAJ_1.Speed", "10")
        mb.write("MAJ_1.AccelRate", "100")
        mb.trigger("MAJ_1")
        mb.step(100)
        values = {}
        for name in ("Axis1.CommandPositionREAL", "Axis1.CommandVelocityREAL"):
            tag = mb.map.tag(name)
            assert tag.type == TagType.REAL and tag.address % 2 == 0
            r = mb.run(tag.address, "-t", "4:float", "-B", "-c", "1")
            assert r.returncode == 0, r.stderr
            ((ref, text),) = LINE.findall(r.stdout)
            assert int(ref) == tag.address
            values[name] = float(text)
        assert values == {"Axis1.CommandPositionREAL": 1.5, "Axis1.CommandVelocityREAL": 10.0}
        # the mirror is read-only, as the LREAL it copies
        tag = mb.map.tag("Axis1.CommandPositionREAL")
        r = mb.run(tag.address, "-t", "4:float", "-B", values=("2.5",))
        assert r.returncode != 0 and "Illegal data address" in r.stderr
