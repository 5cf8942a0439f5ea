"""The role extension of Modbus/TCP Security certificates: an ASN.1 UTF8String in DER
(tag 0x0C, then the length: one byte below 128, else 0x80 | n followed by n length
bytes, then the UTF-8 bytes), and what the certificate's role grants."""

from __future__ import annotations

import pytest

from motion_server.frontends.modbus_tls import MAX_ROLE_BYTES, utf8string
from motion_server.safety.roles import Role, RoleRegisters
from motion_server.tagmap import build_tagmap
from tests.modbus_support import modbus_site


def test_short_and_long_form_lengths() -> None:
    assert utf8string(b"\x0c\x08operator") == "operator"
    assert utf8string(b"\x0c\x00") == ""
    text = "r" * 200  # 200 > 127: long form, one length byte (0xC8)
    assert utf8string(b"\x0c\x81\xc8" + text.encode()) == text
    assert utf8string(b"\x0c\x82\x00\x05admin") == "admin"  # a non-minimal length is read too
    german = "Bediener-Ä".encode()  # Ä is two bytes in UTF-8: 11 bytes for 10 letters
    assert len(german) == 11
    assert utf8string(b"\x0c\x0b" + german) == "Bediener-Ä"


@pytest.mark.parametrize(
    "der",
    [
        b"",
        b"\x0c",
        b"\x13\x05admin",  # a PrintableString
        b"\x0c\x06admin",  # the length claims one byte more
        b"\x0c\x04admin",  # ... or one less
        b"\x0c\x80admin",  # indefinite length
        b"\x0c\x83\x00\x00\x05admin",  # three length bytes
        b"\x0c\x81",  # the length byte missing
        b"\x0c\x81\xff" + b"a" * 255 + b"x",  # over length
        b"\x0c\x82\x01\x00" + b"a" * (MAX_ROLE_BYTES + 1),  # 256 bytes: too long for a role
    ],
)
def test_anything_else_is_refused(der: bytes) -> None:
    with pytest.raises(ValueError):
        utf8string(der)


def test_invalid_utf8_is_refused() -> None:
    with pytest.raises(UnicodeDecodeError):  # a ValueError too
        utf8string(b"\x0c\x02\xc3\x28")


def test_what_each_role_may_write() -> None:
    tagmap = build_tagmap(modbus_site())
    rules = RoleRegisters(tagmap)
    speed, step = tagmap.tag("MAJ_1.Speed"), tagmap.tag("Clock.StepCycles")
    assert rules.write_refused(Role.VIEWER, speed.address, 2) == "role viewer may not write"
    assert rules.write_refused(Role.OPERATOR, speed.address, 2) is None
    refused = rules.write_refused(Role.OPERATOR, step.address, 2)
    assert refused is not None and str(step.address) in refused
    assert rules.write_refused(Role.ADMIN, step.address, 2) is None
    assert rules.admin_only == {
        a
        for t in tagmap
        if t.writable and t.folder.value == "Clock"
        for a in range(t.address, t.address + t.count)
    }
