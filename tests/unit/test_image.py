"""The shared image and the write queue's packets: what the scan and the front-ends
exchange, checked without a server."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest

from motion_server import config
from motion_server.image import wire
from motion_server.image.buffer import (
    META_WORDS,
    ImageError,
    ImageReader,
    ImageWriter,
    Meta,
    create_shared,
    image_bytes,
    map_shared,
)
from motion_server.instructions import MotionSystem
from motion_server.safety.client import ClientInfo
from motion_server.tagmap import TagImage, WordOrder, build_tagmap
from motion_server.tagmap.registers import RegisterEncoder, RegisterWrites

SLOTS = 5000


def _writer(fd: int, snapshots: int) -> None:
    """Publish ``snapshots`` snapshots whose every value and tick equal their number."""
    memory = map_shared(fd, image_bytes(SLOTS), writable=True)
    w = ImageWriter(memory, SLOTS, 7)
    values = np.zeros(SLOTS)
    meta = np.zeros(META_WORDS, dtype=np.int64)
    for k in range(1, snapshots + 1):
        values[:] = k
        meta[Meta.TICK] = k
        w.publish(values, meta)


def test_a_reader_never_sees_half_a_cycle() -> None:
    """A writer process publishes as fast as it can; every snapshot the reader copies
    holds one cycle only (all values equal to its tick) and they never go back."""
    fd = create_shared(image_bytes(SLOTS))
    try:
        memory = map_shared(fd, image_bytes(SLOTS), writable=True)
        ImageWriter(memory, SLOTS, 7)  # laid out before the reader attaches
        reader = ImageReader(map_shared(fd, image_bytes(SLOTS), writable=False), SLOTS, 7)
        proc = multiprocessing.get_context("fork").Process(target=_writer, args=(fd, 20_000))
        proc.start()
        seen = last = 0
        while proc.is_alive() or last < 20_000:
            snap = reader.snapshot()
            tick = snap.tick
            assert tick >= last
            assert snap.values.min() == snap.values.max() == tick
            seen += tick != last
            last = tick
            if not proc.is_alive() and reader.published == snap.count:
                break
        proc.join()
        assert last == 20_000 and seen > 10  # it saw many cycles, each whole
    finally:
        os.close(fd)


def test_a_reader_refuses_an_image_of_another_map() -> None:
    buf = bytearray(image_bytes(10))
    ImageWriter(buf, 10, fingerprint=1)
    with pytest.raises(ImageError, match="another site map"):
        ImageReader(buf, 10, fingerprint=2)
    with pytest.raises(ImageError, match="does not hold"):
        ImageReader(bytearray(image_bytes(10)), 10, fingerprint=1)


def test_a_large_batch_travels_in_fragments_and_arrives_whole() -> None:
    client = ClientInfo("opcua", "10.1.2.3", 4567, 89, "operator1", "operator")
    items = [(k, k * 0.5 - 1e300) for k in range(20_000)]
    packets = wire.encode_batch(wire.Batch(42, client, items))
    assert len(packets) > 1 and all(len(p) <= wire.MAX_PACKET for p in packets)
    assembler = wire.BatchAssembler()
    results = [assembler.feed(p) for p in packets]
    assert results[:-1] == [None] * (len(packets) - 1)
    batch = results[-1]
    assert batch is not None and batch.seq == 42
    assert batch.client == client and batch.items == items


def test_acks_hellos_and_malformed_packets() -> None:
    ack = wire.Ack(7, 123456789, 50, wire.Result.APPLIED)
    assert wire.decode_ack(wire.encode_ack(ack)) == ack
    assert wire.decode_hello(wire.encode_hello(2, 4242, 99)) == (2, 4242, 99)
    with pytest.raises(wire.WireError):
        wire.header(b"\x04")
    with pytest.raises(wire.WireError):
        wire.header(bytes([200, 0, 0, 0, 1, 0, 0, 0]))
    good = wire.encode_batch(wire.Batch(1, ClientInfo("modbus", "h"), [(1, 2.0)]))[0]
    with pytest.raises(wire.WireError):
        wire.BatchAssembler().feed(good[:-3])  # an item cut short
    with pytest.raises(wire.WireError):
        wire.decode_ack(wire.encode_ack(ack) + b"x")


@pytest.mark.parametrize("order", ["big", "little"])
def test_all_registers_at_once_equal_the_encoding_tag_by_tag(order: str) -> None:
    """The front-ends' vectorised encoder against the tag image's one-tag encoders, on
    the demo map with motion under way (negative, fractional and wrapped values)."""
    site = config.load()
    site = site.model_copy(update={"modbus": site.modbus.model_copy(update={"word_order": order})})
    system: MotionSystem = site.build()
    image = TagImage(build_tagmap(site), system)  # operands exact in binary32 (REAL)
    for axis in (2, 3):
        image.write_many([("MSO_1.Axis", axis), ("MSO_1.Execute", True)])
        system.cycle()
        image.write("MSO_1.Execute", False)
        system.cycle()
    jog = [("MAJ_1.Axis", 3), ("MAJ_1.Speed", 3000.0), ("MAJ_1.Direction", 1)]
    move = [("MAM_1.Axis", 2), ("MAM_1.Position", -12.375)]
    image.write_many([*jog, *move, ("MAJ_1.Execute", True), ("MAM_1.Execute", True)])
    system.cycle(60)
    tags = image.map.tags
    values = np.array([float(image.read(t)) for t in tags])
    assert (values < 0).any() and (values != np.round(values)).any()
    encoder = RegisterEncoder(tags, WordOrder(order), max(b.end for b in image.map.blocks))
    regs = encoder.encode(values)
    for block in image.map.blocks:
        expected = image.read_registers(block.base, block.size)
        assert regs[block.base : block.end].tolist() == expected, block.owner
    # and the writes decode back to the values they came from
    writes = RegisterWrites(tags, WordOrder(order))
    block = image.map.block("MAM_1")
    span = block.command_end - block.command_start
    current = regs[block.command_start : block.command_end].tolist()
    decoded = dict(writes.updates(block.command_start, current, lambda a, n: regs[a : a + n]))
    assert {t.name: v for t, v in decoded.items()} == {
        t.name: image.read(t) for t in decoded
    } and span > 0
