"""The one reader of the files the server is given: regular files of a bounded size,
UTF-8; each refusal is one line, which the site map, the retain file and the snapshots word
their own way."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from motion_server.safety import retain
from motion_server.scan import snapshots
from motion_server.textfile import Refusal, TextFileError, read_text_file


def test_a_fifo_is_refused_without_waiting_for_a_writer(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(TextFileError) as err:
        read_text_file(fifo, 100)  # would block forever if it were opened for reading
    assert err.value.refusal == Refusal.NOT_REGULAR


def test_size_bound_and_utf8_line(tmp_path: Path) -> None:
    big = tmp_path / "big"
    big.write_bytes(b"x" * 101)
    with pytest.raises(TextFileError) as err:
        read_text_file(big, 100)
    assert (err.value.refusal, err.value.size) == (Refusal.TOO_LARGE, 101)
    exact = tmp_path / "exact"
    exact.write_bytes(b"y" * 100)
    assert read_text_file(exact, 100) == "y" * 100
    latin = tmp_path / "latin"
    latin.write_bytes(b"one\ntwo\ncaf\xe9\n")
    with pytest.raises(TextFileError) as err:
        read_text_file(latin, 100)
    assert (err.value.refusal, err.value.line) == (Refusal.NOT_UTF8, 3)


def test_a_missing_file_is_left_to_the_caller(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError):
        read_text_file(tmp_path / "none", 100)
    assert retain.load(tmp_path / "none", "site") is None  # no retain file yet: fresh


def test_retain_and_snapshot_word_their_refusals(tmp_path: Path) -> None:
    folder = tmp_path / "dir"
    folder.mkdir()
    with pytest.raises(
        retain.RetainError, match=r"dir: cannot read the retain file: not a regular file$"
    ):
        retain.load(folder, "site")
    with pytest.raises(snapshots.SnapshotError, match=r"dir: not a regular file$"):
        snapshots.header(folder)
    latin = tmp_path / "latin"
    latin.write_bytes(b"\xff")
    with pytest.raises(retain.RetainError, match=r"torn or corrupt retain file \(not UTF-8\)$"):
        retain.load(latin, "site")
    latin.write_bytes(b"\xff\n")  # a snapshot's header line is UTF-8 (its state is not)
    with pytest.raises(snapshots.SnapshotError, match=r"corrupt snapshot header \(not UTF-8\)$"):
        snapshots.header(latin)
    with pytest.raises(snapshots.SnapshotError, match=r"none: no such snapshot$"):
        snapshots.header(tmp_path / "none")
