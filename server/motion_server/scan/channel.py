"""The scan's end of one ``SOCK_SEQPACKET`` socket: a front-end's write queue, or the
supervisor's control channel. Never blocks: packets are read until none is left, and an
answer the peer does not take is kept (up to a bound) rather than waited for.

The peer's end of a front-end channel stays open in the supervisor, which hands it to
the front-end process it starts after one died; the new process says HELLO first, so the
channel outlives any one front-end."""

from __future__ import annotations

import contextlib
import logging
import socket
from collections import deque

from ..image import wire

log = logging.getLogger("motion_server.scan")

#: channel numbers (also the index of their applied sequence in the image's meta words)
CONTROL = 0
MODBUS = 1
OPCUA = 2
LOCAL = 3
WEB = 4
NAMES = {CONTROL: "supervisor", MODBUS: "Modbus", OPCUA: "OPC UA", LOCAL: "local", WEB: "web"}
#: answers kept for a peer that does not read them before it is cut off
OUTBOX_LIMIT = 10_000
_RECV = 1 << 16


class Channel:
    def __init__(self, sock: socket.socket, number: int, name: str = "") -> None:
        sock.setblocking(False)
        self.sock = sock
        self.number = number
        self.name = name or NAMES.get(number, f"channel {number}")
        self.assembler = wire.BatchAssembler()
        self.outbox: deque[bytes] = deque()
        self.closed = False
        #: a front-end's HELLO was accepted (the control channel needs none)
        self.welcomed = number == CONTROL
        self.peer_pid = 0

    def fileno(self) -> int:
        return self.sock.fileno()

    def receive(self) -> list[bytes]:
        """Every packet waiting (an empty list when none); marks the channel closed on EOF."""
        out: list[bytes] = []
        if self.closed:
            return out
        while True:
            try:
                data = self.sock.recv(_RECV)
            except BlockingIOError:
                break
            except OSError as exc:
                log.warning("%s channel: %s", self.name, exc)
                self.closed = True
                break
            if not data:
                self.closed = True
                break
            out.append(data)
        return out

    def send(self, packet: bytes) -> None:
        """Send now, or keep it for the next :meth:`flush` when the peer is behind."""
        if self.closed:
            return
        if self.outbox:
            self.outbox.append(packet)
            self.flush()
            return
        try:
            self.sock.send(packet)
        except BlockingIOError:
            self.outbox.append(packet)
        except OSError:
            self.closed = True

    def flush(self) -> None:
        while self.outbox and not self.closed:
            try:
                self.sock.send(self.outbox[0])
            except BlockingIOError:
                if len(self.outbox) > OUTBOX_LIMIT:
                    log.warning("%s channel: the peer reads no answers; forgotten", self.name)
                    self.reset()
                return
            except OSError:
                self.closed = True
                return
            self.outbox.popleft()

    def drain(self, timeout: float) -> bool:
        """Send what the outbox still holds, waiting up to ``timeout`` seconds for the
        peer (the scan's last words before it exits: the retained state and STOPPED
        on the control channel, kept when the socket's buffer was full). True when
        nothing is left."""
        if self.closed or not self.outbox:
            return not self.outbox
        try:
            self.sock.settimeout(timeout)
            while self.outbox:
                self.sock.send(self.outbox[0])
                self.outbox.popleft()
        except OSError as exc:  # TimeoutError included
            log.warning("%s channel: %d packets not taken: %s", self.name, len(self.outbox), exc)
            return False
        finally:
            with contextlib.suppress(OSError):
                self.sock.setblocking(False)
        return True

    def reset(self) -> None:
        """Forget the peer: nothing more is accepted until its next HELLO (a front-end
        that was restarted, or one that sent something it should not have)."""
        self.welcomed = self.number == CONTROL
        self.assembler.reset()
        self.outbox.clear()

    def close(self) -> None:
        self.closed = True
        self.outbox.clear()
        with contextlib.suppress(OSError):
            self.sock.close()
