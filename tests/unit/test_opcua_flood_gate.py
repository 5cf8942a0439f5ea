"""The OPC UA front-end's flood gate: at most LINES lines per window, the rest counted and
reported in one line, no traceback (a fake clock)."""

from __future__ import annotations

import logging

import pytest

from motion_server.frontends.opcua_log import FloodGate


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def gate() -> FloodGate:
    return FloodGate(lines=3, window=10.0, clock=Clock())


def test_lines_past_the_budget_are_counted_and_reported_once_the_window_is_over(
    gate: FloodGate, caplog: pytest.LogCaptureFixture
) -> None:
    logger = logging.getLogger("motion_server.opcua")
    logger.addFilter(gate)
    clock = gate.clock
    assert isinstance(clock, Clock)
    try:
        with caplog.at_level(logging.INFO):
            for i in range(10):
                logger.info("refused %d", i)
            assert [r.getMessage() for r in caplog.records] == [f"refused {i}" for i in range(3)]
            clock.now = 9.9
            gate.flush()  # the window is not over
            assert len(caplog.records) == 3
            clock.now = 10.0
            gate.flush()
            assert caplog.records[-1].getMessage() == (
                "OPC UA: 7 more log lines suppressed in the last 10 s (at most 3 per 10 s)"
            )
            logger.info("next")  # a new window
            assert caplog.records[-1].getMessage() == "next"
            assert gate.suppressed == 7
    finally:
        logger.removeFilter(gate)


def test_a_line_that_passes_keeps_its_exception_in_one_line_without_the_traceback(
    gate: FloodGate, caplog: pytest.LogCaptureFixture
) -> None:
    logger = logging.getLogger("asyncua.server.uaprocessor")
    logger.addFilter(gate)
    try:
        with caplog.at_level(logging.INFO):
            try:
                raise ValueError("7 is not a valid TimestampsToReturn")
            except ValueError:
                logger.exception("Error while processing message")
        (record,) = caplog.records
        assert record.exc_info is None
        assert record.getMessage() == (
            "Error while processing message (ValueError: 7 is not a valid TimestampsToReturn)"
        )
        assert "Traceback" not in caplog.text
    finally:
        logger.removeFilter(gate)


def test_install_guards_every_asyncua_logger_and_remove_takes_it_off() -> None:
    import asyncua.server.uaprocessor  # noqa: F401  (its module logger exists)

    gate = FloodGate()
    gate.install()
    try:
        for name in ("motion_server.opcua", "asyncua.server.uaprocessor"):
            assert gate in logging.getLogger(name).filters
    finally:
        gate.remove()
    assert gate not in logging.getLogger("asyncua.server.uaprocessor").filters
