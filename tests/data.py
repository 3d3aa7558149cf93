"""Where the shared data lies: ``../shared/data`` beside the repository, never copied here."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
DATA_ROOT = REPO_ROOT.parent / "shared" / "data"
MOT15_ROOT = DATA_ROOT / "mot15"
MOT15_SEQUENCES = (
    sorted(p.name for p in MOT15_ROOT.iterdir() if p.is_dir()) if MOT15_ROOT.is_dir() else []
)


def require_data() -> None:
    """Fails loudly (never skips) when the shared data folder is missing."""
    if not MOT15_ROOT.is_dir():
        pytest.fail(f"shared data not found at {MOT15_ROOT}; clone the repo beside ../shared")
