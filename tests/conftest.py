"""Shared pytest fixtures."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _ci() -> bool:
    """True when the ``CI`` environment variable is set to a true value."""
    return os.environ.get("CI", "").strip().lower() in {"1", "true", "yes", "on", "y", "t"}


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data`` beside the repository.

    Skips the test when the folder is absent, except under ``CI`` (set to a true value):
    CI must run the real-data tests, so there the absence is a failure.
    """
    if not SHARED_DATA.is_dir():
        message = f"../shared/data not found: {SHARED_DATA}"
        if _ci():
            pytest.fail(f"{message} (CI is set: CI must run the real-data tests)")
        pytest.skip(message)
    return SHARED_DATA
