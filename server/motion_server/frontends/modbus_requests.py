"""Modbus requests served on the scan's image (:class:`~.view.ImageView`).

:class:`RequestServer` answers one request ADU at a time for the connections of
:mod:`.modbus`: the unit id (0B for another one), the request's own checks
(:func:`.modbus_pdu.decode`: 01, 03), then the image's, in the order the Modbus
Application Protocol gives (count, then address, then processing):

- FC3 reads the registers of the snapshot the scan published last (with this front-end's
  writes the scan has not applied yet laid over it);
- FC6, FC16, FC22 and FC23 write: every register in the map and in a command region
  (02), allowed by ``[modbus.access]`` and by the client's role (02: the certificate's on
  Modbus/TCP Security, the site's plain role on plain Modbus TCP), a value each tag can
  hold (03), then queued for the scan (04 when it cannot take writes). FC22 applies its
  masks to the register as the client last saw it: (current AND and) OR (or AND NOT
  and). FC23 checks its read range before writing and reads after the write.

A write whose answer must wait (a ``Clock.Step``: once its cycles ran; with the manual
clock every write: once applied) gets a coroutine instead of an answer; the connection
serves nothing after it until it is done. Requests are served ``writing_as`` their
client, so watchdogs and the audit log know who wrote; every refused write (by the
rules, the image, the unit id or the request's own checks) is audited with its reason,
its function code and the registers it would have written.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..safety.access import AccessPolicy
from ..safety.audit import AuditLog
from ..safety.client import ClientInfo, writing_as
from ..safety.roles import Role, RoleRegisters
from ..tagmap import AddressError, BadValueError, ReadOnlyError
from .comm_faults import CommFaults
from .link import Ticket, WriteRefused
from .modbus_pdu import (
    WRITE_FUNCTION_CODES,
    ExceptionCode,
    FunctionCode,
    PduError,
    Request,
    adu,
    decode,
    exception_answer,
    read_answer,
    write_answer,
)
from .modbus_protocol import Answer
from .view import ImageView, ScanUnavailable, outcome

log = logging.getLogger("motion_server.modbus")


class RequestServer:
    """Serves requests for unit ``unit_id`` (0: every unit id) on ``image``; counts
    :attr:`requests` and the :attr:`exceptions` answered."""

    def __init__(
        self,
        image: ImageView,
        unit_id: int,
        policy: AccessPolicy | None = None,
        audit: AuditLog | None = None,
    ) -> None:
        self.image = image
        self.unit_id = unit_id
        self.policy = policy
        self.audit = audit
        self.requests = 0
        self.exceptions = 0
        self._roles = RoleRegisters(image.map)
        #: the communication fault the Clock tags ask for
        self.faults = CommFaults(image)

    def answer(self, client: ClientInfo, tid: int, unit: int, pdu: bytes) -> Answer:
        """The answer ADU to one request of ``client`` (or a coroutine producing it),
        delayed or dropped while a communication fault is set for this client
        (:class:`~.comm_faults.CommFaults`: decided when the request arrives, so the write
        that sets the fault is answered)."""
        fault = self.faults.applies(client)
        answer = self._answer(client, tid, unit, pdu)
        return answer if fault is None else fault.apply(answer)

    def _answer(self, client: ClientInfo, tid: int, unit: int, pdu: bytes) -> Answer:
        self.requests += 1
        fc = pdu[0]
        if self.unit_id and unit != self.unit_id:
            code = ExceptionCode.GATEWAY_TARGET_FAILED_TO_RESPOND
            why = f"unknown unit id {unit} (served: {self.unit_id})"
            return self._refused(client, tid, unit, fc, code, why, _writes(pdu))
        try:
            request = decode(pdu)
        except PduError as exc:
            return self._refused(client, tid, unit, fc, exc.code, str(exc), exc.writes)
        if request.write is None:
            assert request.read is not None
            try:
                data = self._read(*request.read)
            except Exception as exc:
                code, why = self._failure(request, exc)
                return self._refused(client, tid, unit, fc, code, why, None)
            return adu(tid, unit, read_answer(fc, data))
        with writing_as(client):
            try:
                ticket = self._write(client, request)
                if ticket.waits:
                    return self._answer_later(client, tid, unit, request, pdu, ticket)
                return adu(tid, unit, self._written(request, pdu))
            except Exception as exc:
                code, why = self._failure(request, exc)
                return self._refused(client, tid, unit, fc, code, why, request.write)

    async def _answer_later(
        self,
        client: ClientInfo,
        tid: int,
        unit: int,
        request: Request,
        pdu: bytes,
        ticket: Ticket,
    ) -> bytes:
        """The answer once the scan acknowledged the write (a Clock.Step: once its cycles
        ran; with the manual clock every write)."""
        with writing_as(client):
            try:
                await outcome(ticket)
                return adu(tid, unit, self._written(request, pdu))
            except Exception as exc:
                code, why = self._failure(request, exc)
                return self._refused(client, tid, unit, pdu[0], code, why, request.write)

    def _read(self, address: int, count: int) -> bytes:
        """``count`` registers from ``address`` as big-endian words (AddressError)."""
        image = self.image
        image.check(address, count, write=False)
        regs = image.registers()[address : address + count]
        if len(regs) < count:  # unused registers at the end of the last block read 0
            regs = np.concatenate((regs, np.zeros(count - len(regs), dtype=np.uint16)))
        return regs.astype(">u2").tobytes()

    def _write(self, client: ClientInfo, request: Request) -> Ticket:
        """Check and queue the write of ``request`` (the exceptions say why not)."""
        image = self.image
        assert request.write is not None
        address, count = request.write
        image.check(address, count, write=True)
        if request.read is not None:  # FC23: the read is checked before anything is written
            image.check(*request.read, write=False)
        if self.policy is not None:
            reason = self.policy.write_refused(client.address, address, count)
            if reason is not None:
                raise PermissionError(reason)
        # Modbus/TCP Security: the certificate's role; plain Modbus TCP: the site's plain role
        if client.role:
            role = Role.named(client.role)
        else:
            role = self.policy.plain.role if self.policy is not None else Role.ADMIN
        reason = self._roles.write_refused(role, address, count)
        if reason is not None:
            raise PermissionError(reason)
        values: Sequence[int] = request.values
        if request.function == FunctionCode.MASK_WRITE_REGISTER:
            and_mask, or_mask = request.masks
            current = image.read_registers(address, 1, check=False)[0]
            values = [(current & and_mask) | (or_mask & ~and_mask & 0xFFFF)]
        return image.write_registers(address, values, check=False)

    def _written(self, request: Request, pdu: bytes) -> bytes:
        """The answer PDU of a write that went through (FC23: with the registers read)."""
        if request.read is not None:
            return read_answer(request.function, self._read(*request.read))
        return write_answer(request, pdu)

    def _failure(self, request: Request, exc: Exception) -> tuple[ExceptionCode, str]:
        """The exception code and reason for ``exc`` raised while serving ``request``."""
        what = f"FC{int(request.function)} {request.write or request.read}"
        if isinstance(exc, AddressError | ReadOnlyError | PermissionError):
            log.debug("%s: %s", what, exc)
            return ExceptionCode.ILLEGAL_DATA_ADDRESS, str(exc)
        if isinstance(exc, BadValueError):
            log.info("%s refused: %s", what, exc)
            return ExceptionCode.ILLEGAL_DATA_VALUE, str(exc)
        if isinstance(exc, ScanUnavailable):
            log.warning("%s: %s", what, exc)
            return ExceptionCode.SERVER_DEVICE_FAILURE, str(exc)
        if isinstance(exc, WriteRefused):
            log.info("%s: %s", what, exc)
            return ExceptionCode.SERVER_DEVICE_FAILURE, str(exc)
        # never let one request take the server down
        log.error("%s failed", what, exc_info=exc)
        return ExceptionCode.SERVER_DEVICE_FAILURE, f"internal error: {type(exc).__name__}"

    def _refused(
        self,
        client: ClientInfo,
        tid: int,
        unit: int,
        fc: int,
        code: ExceptionCode,
        why: str,
        writes: tuple[int, int] | None,
    ) -> bytes:
        """An exception answer; a refused write is audited with its reason and registers."""
        self.exceptions += 1
        if self.audit is not None and fc in WRITE_FUNCTION_CODES:
            fields: dict[str, Any] = {"function_code": fc}
            reason = why
            if writes is not None:
                span = f"{writes[0]}+{writes[1]}"
                fields["registers"] = span
                reason = f"{span}: {why}"
            with writing_as(client):
                self.audit.refused(reason, **fields)
        return adu(tid, unit, exception_answer(fc, code))


def _writes(pdu: bytes) -> tuple[int, int] | None:
    """The registers a request would write, as far as its PDU says (for the audit)."""
    if pdu[0] not in WRITE_FUNCTION_CODES:
        return None
    try:
        return decode(pdu).write
    except PduError as exc:
        return exc.writes
