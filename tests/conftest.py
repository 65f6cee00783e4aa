"""Fixtures shared by the test modules."""

from __future__ import annotations

import signal

import pytest


def sigint_as_in_a_terminal() -> None:
    """A child process's ``preexec_fn``: SIGINT at its default, so that Python raises
    ``KeyboardInterrupt`` on it as in a terminal, even where the suite runs as a background
    job whose children are born ignoring SIGINT."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def ctrl_c_raises():
    """SIGINT raises KeyboardInterrupt in this process while the test runs (as in a terminal,
    even where the suite runs as a background job that ignores it)."""
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, old)
