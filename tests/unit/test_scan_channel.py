"""The scan's end of a SEQPACKET channel: what it keeps when the peer is behind, and
what it still sends before the scan process exits."""

from __future__ import annotations

import socket
import threading
import time

from motion_server.scan.channel import CONTROL, Channel


def test_packets_the_peer_did_not_take_are_kept_then_drained_before_exit() -> None:
    mine, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    ch = Channel(mine, CONTROL)
    packets = [bytes([k % 256]) * 100 for k in range(600)]
    for p in packets:  # the peer reads nothing meanwhile
        ch.send(p)
    # the socket's buffer holds a few hundred unread packets: the rest waits in the
    # outbox rather than being lost or blocking the scan
    assert ch.outbox
    got: list[bytes] = []

    def slow_reader() -> None:
        time.sleep(0.2)
        while len(got) < len(packets):
            got.append(peer.recv(1 << 16))

    reader = threading.Thread(target=slow_reader)
    reader.start()
    assert ch.drain(5.0)
    reader.join(5.0)
    assert got == packets and not ch.outbox
    mine.close()
    peer.close()


def test_drain_gives_up_after_its_timeout_when_the_peer_never_reads() -> None:
    mine, peer = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    ch = Channel(mine, CONTROL)
    for k in range(600):
        ch.send(bytes([k % 256]) * 100)
    left = len(ch.outbox)
    assert left > 0
    t0 = time.monotonic()
    assert not ch.drain(0.2)
    assert 0.15 <= time.monotonic() - t0 < 2.0
    assert len(ch.outbox) == left  # kept, nothing half sent
    mine.close()
    peer.close()
