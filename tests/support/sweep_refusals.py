"""The check that a bad sweep is refused before any of its cases runs, shared by the sweep tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from heliostep.errors import InputError
from heliostep.sweep import run_sweep


def assert_refused_before_any_case(sweep: Path, results: Path, client, words) -> None:
    """``run_sweep(sweep)`` raises InputError naming ``sweep`` and each of ``words``; no case ran, no table made."""
    ran = []
    with pytest.raises(InputError) as error:
        run_sweep(sweep, results, client=client, on_result=ran.append)
    message = str(error.value)
    assert str(sweep) in message
    for word in words:
        assert word in message
    assert not ran and not results.exists()
