"""Shared fixtures: the data in ../shared/data (always present in CI, never copied here).

Test helpers are imported one way only, as package modules from the repository root
(``from tests.<package>.<module> import name``, e.g. ``from tests.data import MOT15_ROOT``);
never relative imports, ``sys.path`` changes, or imports from a ``conftest.py`` or a test
module; fixtures live in ``conftest.py`` files.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.cli_workspace import build_workspace
from tests.data import DATA_ROOT, MOT15_ROOT, require_data


@pytest.fixture(scope="session")
def mot15_root() -> Path:
    require_data()
    return MOT15_ROOT


@pytest.fixture(scope="session")
def data_root() -> Path:
    require_data()
    return DATA_ROOT


@pytest.fixture
def workspace(tmp_path) -> dict[str, str]:
    """Small inputs for CLI refusal tests (tests/cli_workspace.py); their paths by name."""
    require_data()
    return build_workspace(tmp_path)
