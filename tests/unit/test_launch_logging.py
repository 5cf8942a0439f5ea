"""The server's logging in every process: asyncua's report of a refused request."""

from __future__ import annotations

import logging

import pytest

from motion_server.launch import setup_logging


def test_a_service_fault_answered_to_a_client_is_a_warning_not_an_error(
    caplog: pytest.LogCaptureFixture,
) -> None:
    setup_logging("INFO")
    log = logging.getLogger("asyncua.server.uaprocessor")
    with caplog.at_level(logging.INFO):
        # the call asyncua's UaProcessor makes when it answers with a ServiceFault
        log.error(
            "sending service fault response: %s (%s)",
            "The request could not be processed because it specified too many operations.",
            "BadTooManyOperations",
        )
        log.error("some other failure")
    levels = [(r.getMessage()[:30], r.levelname) for r in caplog.records]
    assert levels == [
        ("sending service fault response", "WARNING"),
        ("some other failure", "ERROR"),
    ]
