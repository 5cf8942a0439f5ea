"""Register encoding and the live tag image: writes land in inputs, reads show the cycle."""

from __future__ import annotations

import math
import struct

import pytest

from motion_server import config
from motion_server.instructions import TagType
from motion_server.tagmap import (
    AddressError,
    BadValueError,
    ClockMode,
    ReadOnlyError,
    StandaloneHost,
    TagImage,
    WordOrder,
    build_tagmap,
    decode,
    encode,
)
from motion_server.tagmap.codec import RegisterValueError

BIG, LITTLE = WordOrder.BIG, WordOrder.LITTLE


@pytest.mark.parametrize(
    ("tag_type", "value", "big"),
    [
        (TagType.REAL, 1.0, [0x3F80, 0x0000]),  # IEEE 754: sign 0, exponent 127, mantissa 0
        (TagType.REAL, -2.5, [0xC020, 0x0000]),
        (TagType.LREAL, 1.0, [0x3FF0, 0, 0, 0]),  # exponent 1023
        (TagType.LREAL, 0.1, [0x3FB9, 0x9999, 0x9999, 0x999A]),
        (TagType.DINT, -2, [0xFFFF, 0xFFFE]),
        (TagType.DINT, 0x12345678, [0x1234, 0x5678]),
        (TagType.UDINT, 2**32 - 1, [0xFFFF, 0xFFFF]),
        (TagType.INT, -1, [0xFFFF]),
        (TagType.SINT, -128, [0xFF80]),
    ],
)
def test_word_orders(tag_type: TagType, value: float, big: list[int]) -> None:
    assert encode(tag_type, value, BIG) == big
    assert encode(tag_type, value, LITTLE) == big[::-1]
    assert decode(tag_type, big, BIG) == value
    assert decode(tag_type, big[::-1], LITTLE) == value


def test_a_register_that_is_no_sint_is_refused() -> None:
    with pytest.raises(RegisterValueError):
        decode(TagType.SINT, [0x0080])


@pytest.fixture
def image() -> TagImage:
    site = config.load()
    system = site.build()
    return TagImage(build_tagmap(site), system, StandaloneHost(system, "1.22.333"))


def regs(image: TagImage, name: str) -> list[int]:
    tag = image.map.tag(name)
    return image.read_registers(tag.address, tag.count)


def test_operand_writes_land_in_inputs_and_are_latched_on_the_edge(image: TagImage) -> None:
    maj = image.system["MAJ_1"]
    tag = image.map.tag("MAJ_1.Speed")
    image.write_registers(tag.address, encode(TagType.REAL, 25.0))
    assert maj.inputs["Speed"] == 25.0
    assert image.read("MAJ_1.Speed") == 25.0
    assert maj.op["Speed"] != 25.0  # latched only on the trigger's edge


def test_a_split_write_changes_only_the_words_it_covers(image: TagImage) -> None:
    tag = image.map.tag("MC_MoveAbsolute_1.Position")
    words = encode(TagType.LREAL, 0.1)
    image.write_registers(tag.address, words[:2])  # the high half first
    half = struct.unpack(">d", struct.pack(">4H", *words[:2], 0, 0))[0]
    assert image.read(tag) == half
    image.write_registers(tag.address + 2, words[2:])
    assert image.read(tag) == 0.1


def test_status_words_and_bits_after_a_cycle(image: TagImage) -> None:
    # Axis2: the demo's MC_Power_1 (Enable low) holds Axis1 off every scan
    image.write("MSO_1.Axis", 2)
    image.write("MSO_1.Execute", True)
    assert image.read("MSO_1.DN") is False  # nothing happens until the cycle
    image.write("Clock.Step", True)  # StepCycles defaults to 1
    assert image.read("Clock.Cycle") == 1
    assert image.read("MSO_1.DN") is True
    status = image.map.tag("MSO_1.DN")
    en = image.map.tag("MSO_1.EN")
    assert regs(image, "MSO_1.DN") == [(1 << status.bit) | (1 << en.bit)]  # type: ignore[operator]
    # FLAGS is the Logix word: EN bit 31, DN bit 29
    assert decode(TagType.UDINT, regs(image, "MSO_1.FLAGS")) == (1 << 31) | (1 << 29)
    assert image.read("Axis2.AxisState") == 2  # Servo Control


def test_clock_step_mode_and_diagnostics(image: TagImage) -> None:
    assert image.write_many([("Clock.StepCycles", 50), ("Clock.Step", True)]) == 50
    assert image.read("Clock.Cycle") == 50
    assert image.read("Clock.SimTime") == pytest.approx(50 * 0.002, abs=1e-15)
    assert image.write("Clock.Step", True) == 0  # no edge: nothing more
    assert image.read("Clock.Cycle") == 50
    image.write("Clock.Step", False)
    image.write("Clock.Step", True)
    assert image.read("Clock.Cycle") == 100
    assert image.read("Diagnostics.Heartbeat") == 100
    assert image.read("Clock.Period") == 2.0
    assert [image.read(f"Diagnostics.Version{p}") for p in ("Major", "Minor", "Patch")] == [
        1,
        22,
        333,
    ]
    image.write("Clock.Mode", 0)
    assert image.host.mode == ClockMode.REALTIME
    image.write("Clock.Step", False)
    image.write("Clock.Step", True)  # realtime: Step does nothing
    assert image.read("Clock.Cycle") == 100
    with pytest.raises(BadValueError, match=r"Clock\.Mode"):
        image.write("Clock.Mode", 7)


def test_hand_wheel_input_is_taken_at_the_next_cycle(image: TagImage) -> None:
    image.write("Axis4.FeedbackInput", 12.34)
    assert image.read("Axis4.ActualPosition") == 0.0
    image.write("Clock.Step", True)
    # quantised to the axis's 100 counts per mm: 1234 counts
    assert image.read("Axis4.ActualPosition") == pytest.approx(1234 / 100, abs=1e-12)
    with pytest.raises(BadValueError):
        image.write("Axis4.FeedbackInput", math.inf)


def test_refusals(image: TagImage) -> None:
    with pytest.raises(ReadOnlyError):
        image.write("MAJ_1.DN", True)
    with pytest.raises(ReadOnlyError):
        image.write_registers(image.map.tag("MAJ_1.ERR").address, [0])
    with pytest.raises(AddressError):
        image.read_registers(4999, 2)  # 4999 is outside every block
    with pytest.raises(AddressError):
        image.read_registers(65535, 1)
    with pytest.raises(BadValueError):
        image.write("MAJ_1.Axis", 2**31)  # not a DINT
    with pytest.raises(BadValueError):
        image.write("MAJ_1.Execute", 2)
    # all or nothing: a bad value leaves the good one unwritten
    with pytest.raises(BadValueError):
        image.write_many([("MAJ_1.Speed", 3.0), ("Clock.Mode", 9)])
    assert image.read("MAJ_1.Speed") == 10.0


def test_unused_registers_of_a_block_read_zero(image: TagImage) -> None:
    block = image.map.block("MSO_1")
    tail = image.read_registers(block.end - 10, 10)
    assert tail == [0] * 10
    with pytest.raises(ReadOnlyError):
        image.write_registers(block.end - 10, [1])


def test_the_vectorised_axis_fields_equal_the_per_axis_getters() -> None:
    """``AXIS_ARRAYS`` (``TagImage.axis_values``, what the OPC UA publisher compares)
    read exactly what the per-axis getters read, rotary wrapping included, on both sides
    of zero and of the rollover."""
    from motion_server.kernel import AxisConfig, AxisType
    from motion_server.tagmap.image import AXIS_ARRAYS, AXIS_GETTERS

    from ..support import make_system

    system = make_system(
        AxisConfig(1, "L", AxisType.SERVO, following_error_limit=1e6),
        AxisConfig(2, "R", AxisType.SERVO, rollover=360.0, following_error_limit=1e6),
        AxisConfig(3, "V", AxisType.VIRTUAL, rollover=1.5),
    )
    ctl = system.ctl
    positions = (-1234.567, -360.0, -0.25, 0.0, 359.9999, 360.0, 725.125, 1e9 + 0.3)
    for k, x in enumerate(positions):
        ctl.cmd_pos[:] = x
        ctl.act_pos[:] = x - 0.001 * k
        ctl.cmd_vel[:] = -3.5 * k
        ctl.act_vel[:] = 2.25 * k
        ctl.cmd_acc[:] = 1e3 * k
        for field, vector in AXIS_ARRAYS.items():
            values = vector(ctl)
            for ax in ctl.axes:
                expected = AXIS_GETTERS[field](ax)
                assert values[ax.index] == expected, (field, ax.name, x)
                assert type(float(values[ax.index])) is type(expected)


def test_static_tags_keep_their_value_through_motion_faults_and_shutdown(
    image: TagImage,
) -> None:
    """What ``is_static`` marks (the OPC UA publisher sends it once) does not change when
    axes are powered, moved, faulted and shut down."""
    from motion_server.tagmap.image import is_static

    static = [t for t in image.map if is_static(t)]
    assert {t.field for t in static} >= {"Number", "Type", "AxisCount", "Member1"}
    before = {t.name: image.read(t) for t in static}
    ctl = image.system.ctl
    for ax in ctl.axes:
        if ax.type.name != "FEEDBACK_ONLY":
            ctl.servo_on(ax)
    image.system.cycle(10)
    ctl.fault(ctl.axes[0], 1)
    ctl.group_shutdown(ctl.groups[0].number)
    image.system.cycle(10)
    assert {t.name: image.read(t) for t in static} == before
