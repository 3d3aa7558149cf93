"""Shared fixtures: the data in ../shared/data (always present in CI, never copied here).

Test helpers are imported one way only, as package modules from the repository root
(``from tests.<package>.<module> import name``, e.g. ``from tests.data import MOT15_ROOT``);
never relative imports, ``sys.path`` changes, or imports from a ``conftest.py`` or a test
module; fixtures live in ``conftest.py`` files.
"""

from __future__ import annotations

import gc
import os
from pathlib import Path

import jax
import pytest

from jaxtrack.pipelines.runtime import CACHE_ENV, use_cpu_cores
from tests.cli_workspace import build_workspace
from tests.data import DATA_ROOT, MOT15_ROOT, require_data

# The devices the jaxtrack command makes (one CPU device per core), set before any test
# computes: otherwise whichever test first calls the command's main() in this process
# would decide the devices of every later test.
use_cpu_cores()
# No compilation cache on disk (here and in the commands the tests start): tests count
# compiles, and a test run should not fill the machine's cache folder.
os.environ[CACHE_ENV] = ""


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


#: Memory maps of the test process above which JAX's compiled executables are dropped after a
#: test. Every compiled executable holds memory maps of its own (a run of the Fusion tracker
#: about 700, its step called eagerly 3 frames about 3600) and the kernel allows 65530 per
#: process (``vm.max_map_count``): past it LLVM aborts inside a compile ("Fatal Python error:
#: Aborted" / "Segmentation fault" in ``backend_compile_and_load``), which took down an xdist
#: worker near the end of the suite.
MAX_MEMORY_MAPS = 32768


def _memory_maps() -> int:
    """The number of memory maps of this process (0 where ``/proc`` has none)."""
    try:
        with open("/proc/self/maps", "rb") as maps:
            return sum(1 for _ in maps)
    except OSError:
        return 0


@pytest.fixture(autouse=True)
def _bounded_memory_maps():
    """After each test, drops the compiled executables once the process holds more than
    :data:`MAX_MEMORY_MAPS` memory maps (later tests compile again what they need)."""
    yield
    if _memory_maps() > MAX_MEMORY_MAPS:
        jax.clear_caches()
        gc.collect()
