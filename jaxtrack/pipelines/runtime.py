"""How the ``jaxtrack`` command sets JAX up: CPU devices, XLA's CPU threads and vector width,
and the compilation cache.

All must be set before JAX computes anything, so the command calls them first thing
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
#: Environment variables XLA's CPU client reads, in this order, for the size of its thread
#: pool when JAX creates it (XLA's ``DefaultThreadPoolSize``); unset, one thread per core.
THREAD_ENVS = ("PJRT_NPROC", "NPROC")
#: The thread pool size :func:`use_cpu_threads` sets by default.
DEFAULT_CPU_THREADS = 1
#: XLA's flag for the vector width (bits) its CPU code generator prefers (256 unset).
VECTOR_WIDTH_FLAG = "xla_cpu_prefer_vector_width"
#: XLA's flag for min/max without NaN tests (false unset).
FAST_MIN_MAX_FLAG = "xla_cpu_enable_fast_min_max"
#: The width :func:`use_cpu_vector_width` asks for by default, and the CPU feature (a
#: ``flags`` word of ``/proc/cpuinfo``) it needs.
DEFAULT_VECTOR_WIDTH = 512
VECTOR_WIDTH_FEATURES = {512: "avx512f", 256: "avx2"}


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
        count = _usable_cores()
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


def use_cpu_threads(count: int = DEFAULT_CPU_THREADS) -> int:
    """Sizes XLA's CPU thread pool (one thread by default, instead of one per core).

    XLA:CPU splits every large enough kernel of a program into parts that its thread pool
    runs side by side, and waits for them. The PHD tracker's frame at tracking sizes is about
    200 small kernels (PETS09-S2L1 at 2048 particles, most of a few thousand elements;
    ``benchmarks/phd_trace.py``), and there the split and the wait cost more than the
    second core gives: on one thread the tracker runs PETS09-S2L1 at 1.1-1.3x the frames per
    second of the default pool on 2 cores (README, "Where the PHD step's time goes"). The
    other trackers' frames hold image-sized work that the pool speeds up (Fusion and
    Hierarchical ran 15-30 % slower on one thread), so the ``jaxtrack`` command calls this
    only for the PHD tracker (:func:`jaxtrack.cli.runs_the_phd_tracker`). The programs and
    their results are the same bit for bit: the pool's size changes which thread runs a
    kernel's parts, not the parts.

    It must run before JAX creates its CPU client (the first computation); it changes
    nothing (and returns 0) when the client exists already or when the user chose a size
    (``PJRT_NPROC`` or ``NPROC`` set).

    Args:
        count: the pool's threads, at least 1.

    Returns:
        The size set, or 0 when nothing was changed.

    Raises:
        ValueError: ``count`` below 1.
    """
    if count < 1:
        raise ValueError(f"count must be at least 1, got {count}")
    if any(os.environ.get(name) for name in THREAD_ENVS) or _backends_exist():
        return 0
    os.environ[THREAD_ENVS[0]] = str(int(count))
    return int(count)


def use_cpu_vector_width(bits: int = DEFAULT_VECTOR_WIDTH, fast_min_max: bool = True) -> int:
    """Asks XLA's CPU code generator for ``bits``-wide vectors and plain min/max.

    * ``--xla_cpu_prefer_vector_width=bits``: XLA:CPU emits 256-bit vector code by default,
      also on CPUs with 512-bit registers (AVX-512). The PHD tracker's kernels are
      elementwise loops over particles and particle x detection pairs, which 512-bit
      vectors do in half the instructions.
    * ``--xla_cpu_enable_fast_min_max=true`` (with ``fast_min_max``): ``min`` and ``max``
      compile to one compare-and-select instead of also testing for NaN. Only a NaN operand
      gives another result (a number instead of NaN); the trackers' inputs are checked for
      NaN when read, so a NaN inside a step is a bug either way.

    On the 2-core AVX-512 machine of the README, PETS09-S2L1 at 2048 particles ran at
    1.02-1.10x the frames per second with the first and about 1.03x more with both, and the
    outputs were the same bit for bit on the eleven MOT15 training sequences (README, "Where
    the PHD step's time goes", session 49; tested on TUD-Campus). The ``jaxtrack`` command
    calls it where it sizes the thread pool, for the PHD tracker
    (:func:`jaxtrack.cli.runs_the_phd_tracker`).

    It adds the flags to ``XLA_FLAGS``, which XLA reads when JAX creates its backends (the
    first computation): it must run before that. It changes nothing (and returns 0) when the
    backends exist, when ``XLA_FLAGS`` already chooses a width (the user's choice), or when
    the CPU lacks the registers (``/proc/cpuinfo`` names no ``avx512f`` for 512, no ``avx2``
    for 256; unreadable, as off Linux: nothing is assumed). A min/max choice in
    ``XLA_FLAGS`` is kept too.

    Args:
        bits: 256 or 512.
        fast_min_max: also ask for plain min/max.

    Returns:
        The width set, or 0 when nothing was changed.

    Raises:
        ValueError: ``bits`` other than 256 or 512.
    """
    if bits not in VECTOR_WIDTH_FEATURES:
        raise ValueError(f"bits must be one of {sorted(VECTOR_WIDTH_FEATURES)}, got {bits}")
    flags = os.environ.get("XLA_FLAGS", "")
    if VECTOR_WIDTH_FLAG in flags or _backends_exist():
        return 0
    if VECTOR_WIDTH_FEATURES[bits] not in cpu_features():
        return 0
    added = [f"--{VECTOR_WIDTH_FLAG}={bits}"]
    if fast_min_max and FAST_MIN_MAX_FLAG not in flags:
        added.append(f"--{FAST_MIN_MAX_FLAG}=true")
    os.environ["XLA_FLAGS"] = " ".join([flags, *added]).strip()
    return bits


def cpu_features() -> frozenset[str]:
    """The CPU's feature words (the ``flags`` line of ``/proc/cpuinfo``; empty if unreadable)."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as info:
            for line in info:
                if line.startswith("flags"):
                    return frozenset(line.partition(":")[2].split())
    except OSError:
        pass
    return frozenset()


def cpu_vector_width() -> int:
    """The vector width XLA's CPU code generator is asked for in ``XLA_FLAGS`` (0: not
    chosen, XLA's default of 256)."""
    for flag in os.environ.get("XLA_FLAGS", "").split():
        name, _, value = flag.lstrip("-").partition("=")
        if name == VECTOR_WIDTH_FLAG and value.isdigit():
            return int(value)
    return 0


def cpu_thread_pool_size() -> int:
    """The size of XLA's CPU thread pool as JAX creates (or created) it: ``PJRT_NPROC``,
    else ``NPROC``, else the cores this process may run on (XLA's own rule)."""
    for name in THREAD_ENVS:
        value = os.environ.get(name, "")
        if value.strip().isdigit():
            return int(value)
    return _usable_cores()


def _usable_cores() -> int:
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _backends_exist() -> bool:
    """True once JAX has created its backends (then the CPU client's pool is sized)."""
    from jax._src import xla_bridge  # no public API says whether the backends exist

    return bool(xla_bridge.backends_are_initialized())


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
