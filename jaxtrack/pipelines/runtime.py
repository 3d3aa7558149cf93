"""How the ``jaxtrack`` command sets JAX up: CPU devices and the compilation cache.

Both must be set before JAX computes anything, so the command calls them first thing
(:func:`jaxtrack.cli.main`); a notebook or script calls them right after its imports. Each
leaves a choice the user made alone.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import jax

#: The largest size of the compilation cache; the least recently used programs are dropped
#: beyond it.
CACHE_MAX_BYTES = 2**30
#: Environment variable naming the compilation cache's folder (empty: no cache).
CACHE_ENV = "JAXTRACK_CACHE_DIR"


def use_cpu_cores(count: int | None = None) -> int:
    """Makes JAX show one CPU device per usable core, so that a sweep's groups run side by side.

    On CPU, JAX has one device by default and XLA runs its program's small kernels mostly one
    after another, so a sweep of tracking-size configurations leaves cores idle; with one
    device per core, :func:`~jaxtrack.pipelines.sweep.sweep` runs a group of configurations
    on each (measured on 2 cores: the 162-run PETS09-S2L1 magnitude sweep of
    ``benchmarks/sweep_speed.py`` took 15.0-17.1 s against 18.1-19.6 s on one device, in one
    series; single runs are unchanged, they use the first device). The ``jaxtrack`` command
    calls this at start. It must run before JAX computes anything; it changes nothing (and
    returns 0) when the backends are already initialised, when the user chose a count
    (``XLA_FLAGS=--xla_force_host_platform_device_count=N``, ``JAX_NUM_CPU_DEVICES``,
    ``jax.config.update("jax_num_cpu_devices", N)``), or when there is one core.

    Args:
        count: devices to make (default: the cores this process may run on).

    Returns:
        The number of CPU devices set, or 0 when nothing was changed.
    """
    if count is None:
        count = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    configured = getattr(jax.config, "jax_num_cpu_devices", None)  # JAX >= 0.4.34
    chosen = (
        configured is None
        or configured != -1
        or "xla_force_host_platform_device_count" in os.environ.get("XLA_FLAGS", "")
        or os.environ.get("JAX_NUM_CPU_DEVICES")
    )
    if chosen or not count or count < 2:
        return 0
    try:
        jax.config.update("jax_num_cpu_devices", int(count))
    except RuntimeError:  # the backends are initialised: too late to change the devices
        return 0
    return int(count)


def default_cache_dir() -> Path:
    """``$JAXTRACK_CACHE_DIR``, else ``$XDG_CACHE_HOME/jaxtrack/xla``, else
    ``~/.cache/jaxtrack/xla``."""
    if os.environ.get(CACHE_ENV):
        return Path(os.environ[CACHE_ENV]).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "jaxtrack" / "xla"


def use_compilation_cache(path: str | os.PathLike | None = None) -> Path | None:
    """Keeps the compiled programs on disk, so that a later run skips compiling them.

    A tracker's ``lax.scan`` takes 2-5 s to compile on 2 CPU cores, each time a process runs
    it; JAX's persistent compilation cache stores every program that took at least
    ``jax_persistent_cache_min_compile_time_secs`` (1 s) to compile, keyed by the program,
    the compile options, the devices and the JAX version, so a later process with the same
    setting loads it instead (the same machine code: the same results, bit for bit). The
    cache is capped at :data:`CACHE_MAX_BYTES`, least recently used first out. The
    ``jaxtrack`` command calls this at start.

    It changes nothing (and returns None) when the user chose a cache
    (``JAX_COMPILATION_CACHE_DIR``, ``jax.config.update("jax_compilation_cache_dir", ...)``),
    when ``JAXTRACK_CACHE_DIR`` is set and empty (no cache), or when the folder cannot be
    made (no home folder, no permission).

    Args:
        path: the cache's folder (default :func:`default_cache_dir`).

    Returns:
        The folder in use, or None.
    """
    if jax.config.jax_compilation_cache_dir or os.environ.get("JAX_COMPILATION_CACHE_DIR"):
        return None
    if path is None:
        if os.environ.get(CACHE_ENV) == "":
            return None
        try:
            path = default_cache_dir()
        except RuntimeError:  # no home folder to put it in
            return None
    folder = Path(path).expanduser()
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    # Eviction needs the filelock package (a dependency); without it the cache is unbounded.
    if importlib.util.find_spec("filelock") is not None:
        jax.config.update("jax_compilation_cache_max_size", CACHE_MAX_BYTES)
    return folder
