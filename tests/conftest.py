"""Shared fixtures: the data in ../shared/data (always present in CI, never copied here).

Test helpers are imported one way only, as package modules from the repository root
(``from tests.<package>.<module> import name``, e.g. ``from tests.data import MOT15_ROOT``);
never relative imports, ``sys.path`` changes, or imports from a ``conftest.py`` or a test
module; fixtures live in ``conftest.py`` files.
"""

from __future__ import annotations

import atexit
import gc
import os
import shutil
import tempfile
from pathlib import Path

import jax
import pytest

from jaxtrack.pipelines.runtime import CACHE_ENV, use_cpu_cores, use_cpu_threads
from tests.cli_workspace import build_workspace
from tests.data import DATA_ROOT, MOT15_ROOT, require_data

#: Environment variable naming this test run's compilation cache folder (see below).
TEST_CACHE_ENV = "JAXTRACK_TEST_XLA_CACHE"
#: Programs that compile faster than this are not written to it (writing costs too).
TEST_CACHE_MIN_SECONDS = 0.5

# The devices the jaxtrack command makes (one CPU device per core), set before any test
# computes: otherwise whichever test first calls the command's main() in this process
# would decide the devices of every later test. Likewise XLA's thread pool (the command's
# one thread; the commands and notebooks the tests start inherit it by the environment).
use_cpu_cores()
use_cpu_threads()
# The machine's compilation cache is not used (here and in the commands the tests start): a
# test run should not fill it, nor start from what an earlier run left there.
os.environ[CACHE_ENV] = ""
# One compilation cache of this test run's own instead, in a temporary folder that the first
# process (pytest, or xdist's controller) makes and removes when it exits; the xdist workers,
# the commands the tests start and the notebooks' kernels inherit it by the environment. The
# suite is compile-bound (on 2 cores XLA's compiles take about 4/5 of a test's time), and
# without it every worker and every subprocess compiled the same programs again. A program
# loaded from the cache is the same machine code (same results, bit for bit), and JAX reports
# it as a backend compile like a fresh one, so the tests that count compiles count the same.
if TEST_CACHE_ENV not in os.environ:
    os.environ[TEST_CACHE_ENV] = tempfile.mkdtemp(prefix="jaxtrack-test-xla-")
    atexit.register(shutil.rmtree, os.environ[TEST_CACHE_ENV], ignore_errors=True)
os.environ["JAX_COMPILATION_CACHE_DIR"] = os.environ[TEST_CACHE_ENV]
os.environ["JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS"] = str(TEST_CACHE_MIN_SECONDS)
jax.config.update("jax_compilation_cache_dir", os.environ[TEST_CACHE_ENV])
jax.config.update("jax_persistent_cache_min_compile_time_secs", TEST_CACHE_MIN_SECONDS)


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
