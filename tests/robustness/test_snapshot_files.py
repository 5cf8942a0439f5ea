"""Crafted snapshot files: each is refused in one line that names the file and the reason,
and the controller is left exactly as it was (``scan/snapshots.py``).

The cases: the old finding (a file whose retained base is junk, with a recomputed
SHA-256, which ended the scan with ``KeyError: 'axes'``), a forged signature, a file signed
by another installation, truncated and padded files, a header without an end, wrong types
in the header, a link out of the folder, the folder itself a link, a directory, a FIFO (no
hang), a file beyond the size limit, a key others may read, and files signed with the
right key whose state is not a controller of this site (a global the codec refuses, a
state of another shape, a header cycle that is not the state's). The restore is asked the
way a client asks it (``Clock.Snapshot`` and a rising edge of ``Clock.SnapshotRestore``),
and through :meth:`Scan.restore_snapshot`.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from motion_server import config
from motion_server.runtime import Runtime
from motion_server.scan import snapshots, statecodec
from motion_server.tagmap import Folder

N = 5  # the number of the snapshot under attack


def demo_site(tmp: Path) -> config.SiteMap:
    site = config.load(None)
    ctl = site.controller.model_copy(update={"clock": "manual", "status_log_interval": 0.0})
    return site.model_copy(update={"controller": ctl, "data_dir": str(tmp)})


@pytest.fixture
def rt(tmp_path: Path) -> Runtime:
    """A server with Axis1 jogging, snapshot N saved, then ten cycles more."""
    rt = Runtime(demo_site(tmp_path / "data"))
    rt.image.write_many([("MSO_1.Axis", 1), ("MSO_1.Execute", True)])
    rt.cycle(2)
    rt.image.write_many(
        [("MAJ_1.Axis", 1), ("MAJ_1.Speed", 50.0), ("MAJ_1.AccelRate", 500.0),
         ("MAJ_1.DecelRate", 500.0), ("MAJ_1.Execute", True)]
    )  # fmt: skip
    rt.cycle(50)
    rt.scan.save_snapshot(str(N))
    rt.cycle(10)
    return rt


def path(rt: Runtime) -> Path:
    return snapshots.path_of(rt.site, str(N))


def state(rt: Runtime) -> bytes:
    """Everything a client sees of the controller (not the host's Clock and diagnostics)."""
    keep = [
        i
        for i, t in enumerate(rt.layout.tags)
        if t.folder not in (Folder.DIAGNOSTICS, Folder.CLOCK)
    ]
    return bytes(rt.image.values()[keep].tobytes())


def refused(rt: Runtime, *words: str) -> str:
    """Restore N both ways: refused in one line naming the file, nothing changed."""
    before, tick = state(rt), rt.cycle_count
    with pytest.raises(snapshots.SnapshotError) as err:
        rt.scan.restore_snapshot(str(N))
    text = str(err.value)
    assert "\n" not in text and str(path(rt)) in text, text
    for w in words:
        assert w in text, text
    ticket = rt.image.write_many([("Clock.Snapshot", N), ("Clock.SnapshotRestore", True)])
    assert ticket.ack is not None and ticket.ack.result.name in ("REFUSED", "FAILED")
    assert rt.image.read("Clock.SnapshotRestore") is False
    assert rt.cycle_count == tick
    assert state(rt) == before
    rt.cycle(3)  # and the scan goes on
    assert rt.cycle_count == tick + 3
    return text


def header_and_body(p: Path) -> tuple[dict[str, object], bytes]:
    data = p.read_bytes()
    end = data.index(b"\n")
    return json.loads(data[:end]), data[end + 1 :]


def signed(rt: Runtime, head: dict[str, object], body: bytes) -> bytes:
    """A file this installation could have written (its own key)."""
    head = {k: v for k, v in head.items() if k != "hmac"}
    head["size"] = len(body)
    key = snapshots.installation_key(rt.site, create=False)
    head["hmac"] = snapshots._mac(key, snapshots._canonical(head), body)
    return json.dumps(head).encode() + b"\n" + body


def test_the_old_finding_a_junk_base_with_a_recomputed_checksum(rt: Runtime) -> None:
    body = {"site": "demo", "tick": 3, "base": {"format": "junk"}, "records": []}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"))
    digest = hashlib.sha256(text.encode()).hexdigest()
    doc = {"format": "motion-server-snapshot/1", "sha256": digest, "body": body}
    path(rt).write_text(json.dumps(doc) + "\n")
    refused(rt, "not a motion-server-snapshot/2 file")


def test_a_forged_signature(rt: Runtime) -> None:
    head, body = header_and_body(path(rt))
    head["tick"] = 10**9  # the hang of the old design: a huge tick
    head["hmac"] = "0" * 64
    path(rt).write_bytes(json.dumps(head).encode() + b"\n" + body)
    refused(rt, "signature mismatch")


def test_a_file_of_another_installation(rt: Runtime, tmp_path: Path) -> None:
    other = Runtime(demo_site(tmp_path / "elsewhere"))
    other.cycle(7)
    foreign = other.scan.save_snapshot(str(N))
    path(rt).write_bytes(foreign.read_bytes())  # copied in from a shared volume
    refused(rt, "signature mismatch")


@pytest.mark.parametrize(
    ("damage", "words"),
    [
        (lambda d: d[:-40], "truncated or padded"),
        (lambda d: d + b"\0" * 10, "truncated or padded"),
        (lambda d: d[: d.index(b"\n")], "no header line"),
        (lambda d: b"x" * 70000, "no header line"),
        (lambda d: b"", "no header line"),
        (lambda d: b"\xff\xfe\n" + d, "not UTF-8"),
        (lambda d: b'{"format": "motion-server-snapshot/2", "tick": NaN}\n', "not a number"),
        (lambda d: d.replace(b'"tick": ', b'"tick": -', 1), "malformed snapshot: tick"),
        (lambda d: d.replace(b'"tick": ', b'"tick": 1e', 1), "malformed snapshot: tick"),
        (lambda d: d.replace(b'"site": ', b'"site": 7, "x": ', 1), "header field 'site'"),
        (lambda d: b"[1, 2]\n", "not a motion-server-snapshot/2 file"),
        (lambda d: b"[" * 60000 + b"\n", "corrupt snapshot header"),
    ],
)
def test_damaged_files(rt: Runtime, damage: Callable[[bytes], bytes], words: str) -> None:
    path(rt).write_bytes(damage(path(rt).read_bytes()))
    refused(rt, words)


def test_a_flipped_bit_in_the_state(rt: Runtime) -> None:
    data = bytearray(path(rt).read_bytes())
    data[-100] ^= 0x01
    path(rt).write_bytes(bytes(data))
    refused(rt, "signature mismatch")


def test_links_are_not_followed(rt: Runtime, tmp_path: Path) -> None:
    outside = tmp_path / "outside.snap"
    outside.write_bytes(path(rt).read_bytes())  # a sound file, but out of the folder
    path(rt).unlink()
    path(rt).symlink_to(outside)
    refused(rt, "a link")


def test_the_folder_a_link(rt: Runtime, tmp_path: Path) -> None:
    folder = snapshots.directory(rt.site)
    moved = tmp_path / "moved"
    folder.rename(moved)
    folder.symlink_to(moved)
    refused(rt, "the snapshot folder is a link")


def test_not_regular_files(rt: Runtime) -> None:
    path(rt).unlink()
    path(rt).mkdir()
    refused(rt, "not a regular file")
    path(rt).rmdir()
    os.mkfifo(path(rt))  # opened without blocking: refused, never waited on
    refused(rt, "not a regular file")


def test_too_large(rt: Runtime) -> None:
    with path(rt).open("r+b") as f:
        f.truncate(snapshots.MAX_BYTES + 1)  # sparse: no disk used
    refused(rt, "larger than 256 MiB")


def test_a_key_others_may_read(rt: Runtime) -> None:
    os.chmod(snapshots.key_path(rt.site), 0o644)
    refused(rt, "may be read by others")


def test_no_key(rt: Runtime) -> None:
    snapshots.key_path(rt.site).unlink()
    refused(rt, "no snapshot key")


def test_signed_but_holding_a_forbidden_global(rt: Runtime) -> None:
    head, _ = header_and_body(path(rt))
    path(rt).write_bytes(signed(rt, head, pickle.dumps(os.system)))
    refused(rt, "may not hold posix.system")


def test_signed_but_not_a_controller(rt: Runtime) -> None:
    head, _ = header_and_body(path(rt))
    path(rt).write_bytes(signed(rt, head, statecodec.dumps({"axes": []})))
    refused(rt, "not a controller state")
    path(rt).write_bytes(signed(rt, head, b"\x80\x05junk"))
    refused(rt, "malformed snapshot")


def test_signed_but_the_header_cycle_is_not_the_states(rt: Runtime) -> None:
    head, body = header_and_body(path(rt))
    head["tick"] = 10**9
    path(rt).write_bytes(signed(rt, head, body))
    refused(rt, "a state of cycle 52, not 1000000000")


def test_signed_but_of_another_site_map(rt: Runtime, tmp_path: Path) -> None:
    """A state of a controller with other axes, under a header that claims this site."""
    site = demo_site(tmp_path / "x")
    axes = list(site.axes)[:3]
    group = site.groups[0].model_copy(update={"axes": [a.name for a in axes]})
    other = Runtime(site.model_copy(update={"axes": axes, "groups": [group]}))
    other.cycle(52)
    head, _ = header_and_body(path(rt))
    body = snapshots.encode(snapshots.capture(other.scan.system, other.scan.watchdogs))
    path(rt).write_bytes(signed(rt, head, body))
    refused(rt, "its axes are not the site map's")


def test_a_sound_file_still_restores(rt: Runtime) -> None:
    """The fixture's file itself: restored, the controller at its cycle."""
    rt.scan.restore_snapshot(str(N))
    assert rt.cycle_count == 52
    assert np.isfinite(rt.ctl.cmd_pos).all()
    assert os.stat(path(rt)).st_mode & 0o777 == 0o600
    assert os.stat(snapshots.key_path(rt.site)).st_mode & 0o777 == 0o600
    assert os.stat(snapshots.directory(rt.site)).st_mode & 0o777 == 0o700
