"""Shared test helpers: where the real data lives, and the checks every produced mesh must pass."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

DATA = Path(os.environ.get("BITEMESH_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


@pytest.fixture
def shared_data() -> Path:
    """The folder of real data (../shared/data beside the clone); skip where it is absent."""
    if not DATA.is_dir():
        pytest.skip(f"real data folder {DATA} is absent (set BITEMESH_DATA)")
    return DATA
