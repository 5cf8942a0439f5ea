"""Communication faults: answers delayed or dropped, for testing an HMI's timeouts.

The Clock tags say what (``Clock.CommFault``: 1 delay, 2 drop), how long each answer is
late (``Clock.CommDelay``, ms) and to whom (``Clock.CommClientPort``: the client's TCP
port, 0 every client); the scan ends the fault after ``Clock.CommDuration`` ms by setting
``CommFault`` back to 0. Both front-ends read them from the image when a request arrives
and apply them to that request's answer (Modbus TCP, plain and Security: every request;
OPC UA: every service request on a secure channel, ``opcua_wire.GuardedProcessor``):

- delay: the answer goes out ``CommDelay`` ms late; the requests behind it on the same
  connection wait their turn, as on a slow link;
- drop: the request is served (a write is applied) but its answer is never sent, as when
  the answers are lost on the way; the connection stays open.

On OPC UA a delayed request is served once its delay is over (the client sees the same
latency); the channel's Hello, OpenSecureChannel and CloseSecureChannel are not affected.
An answer sent later than its request (a Publish answered when a notification is due) is
judged when it is sent: dropped, or sent ``CommDelay`` ms later.

The decision is taken when the request arrives, so the write that sets a fault is still
answered, and a request that arrived during the fault keeps its fate after it ended.
"""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Coroutine
from dataclasses import dataclass
from typing import Any, TypeVar

from ..safety.client import ClientInfo
from ..tagmap import CommFault
from .view import ImageView

T = TypeVar("T")


@dataclass(frozen=True)
class Fault:
    """The fault applied to one request's answer."""

    mode: CommFault
    delay: float  # seconds

    def apply(self, answer: T | Coroutine[Any, Any, T]) -> Coroutine[Any, Any, T | bytes]:
        """``answer`` (a value or a coroutine producing it) delayed, or dropped (``b""``:
        nothing sent)."""
        return self._delayed(answer) if self.mode == CommFault.DELAY else self._dropped(answer)

    async def _delayed(self, answer: T | Coroutine[Any, Any, T]) -> T | bytes:
        value = await answer if isinstance(answer, Awaitable) else answer
        await asyncio.sleep(self.delay)
        return value

    async def _dropped(self, answer: T | Coroutine[Any, Any, T]) -> T | bytes:
        if isinstance(answer, Awaitable):
            await answer  # served all the same (a write is applied)
        return b""


class CommFaults:
    """Reads the Clock's communication-fault tags from a front-end's image."""

    def __init__(self, image: ImageView) -> None:
        self.image = image
        self._mode = image.slot("Clock.CommFault")
        self._delay = image.slot("Clock.CommDelay")
        self._port = image.slot("Clock.CommClientPort")
        #: answers delayed and dropped so far
        self.delayed = 0
        self.dropped = 0

    def applies(self, client: ClientInfo) -> Fault | None:
        """The fault for a request of ``client`` arriving now (None: answer normally)."""
        return self.for_port(client.port)

    def for_port(self, client_port: int) -> Fault | None:
        """The fault for an answer to the client connected from TCP port ``client_port``."""
        values = self.image.values()
        mode = int(values[self._mode])
        if not mode:
            return None
        port = int(values[self._port])
        if port and port != client_port:
            return None
        fault = CommFault(mode)
        if fault == CommFault.DELAY:
            self.delayed += 1
        else:
            self.dropped += 1
        return Fault(fault, float(values[self._delay]) / 1000.0)
