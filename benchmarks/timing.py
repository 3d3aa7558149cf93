"""Wall-clock timing shared by the benchmark scripts (imported as ``timing``: a script's
own folder is first on ``sys.path``)."""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

from jaxtrack.filters import default_phd_params
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.runtime import (
    DEFAULT_CPU_THREADS,
    DEFAULT_VECTOR_WIDTH,
    cpu_thread_pool_size,
    cpu_vector_width,
    use_cpu_threads,
    use_cpu_vector_width,
)

#: The shared data folder beside the repository.
DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

#: glibc's malloc tunable that asks the kernel for transparent huge pages (``madvise``) on the
#: blocks it maps: a 1e6-particle array then faults in 2 MiB pages instead of 4 KiB ones.
HUGE_PAGES_TUNABLE = "glibc.malloc.hugetlb=1"
#: Where Linux says whether transparent huge pages may be used (``[always]`` or
#: ``[madvise]`` selected; ``[never]``: the tunable has no effect).
THP_SETTING = Path("/sys/kernel/mm/transparent_hugepage/enabled")


def add_huge_pages_option(parser: argparse.ArgumentParser) -> None:
    """``--huge-pages on|off`` (see :func:`use_huge_pages`)."""
    parser.add_argument(
        "--huge-pages",
        choices=("on", "off"),
        default="on",
        help="on (default): run with glibc's malloc on transparent huge pages "
        f"(GLIBC_TUNABLES={HUGE_PAGES_TUNABLE}; the script restarts itself with it where "
        "glibc and the kernel allow it, and keeps a hugetlb value you set); off: as started",
    )


def use_huge_pages(choice: str) -> str:
    """Restarts the script with :data:`HUGE_PAGES_TUNABLE` added to ``GLIBC_TUNABLES`` when
    ``choice`` is ``"on"``, the C library is glibc, the kernel allows transparent huge pages,
    and the environment does not set ``glibc.malloc.hugetlb`` already (glibc reads its
    tunables when a process starts, so the process must start again; the restarted one finds
    the tunable and goes on). Returns ``GLIBC_TUNABLES`` as the process runs with it.

    Why: at 1e6 particles a recursion's fresh buffers (tens of MB each call) are mapped
    anew and fault in page by page; on huge pages the 1e6-particle recursion took 78-110 ms
    against 92-170 ms (2 cores, `phd_step.py`, session 59), smaller sizes unchanged."""
    current = os.environ.get("GLIBC_TUNABLES", "")
    wanted = (
        choice == "on"
        and "glibc.malloc.hugetlb" not in current
        and platform.libc_ver()[0] == "glibc"
        and THP_SETTING.exists()
        and "[never]" not in THP_SETTING.read_text()
    )
    if wanted:
        tunables = ":".join(filter(None, [current, HUGE_PAGES_TUNABLE]))
        sys.stdout.flush()
        os.execve(
            sys.executable, [sys.executable, *sys.argv], {**os.environ, "GLIBC_TUNABLES": tunables}
        )
    return current


def best_time(function, repeats: int) -> float:
    """The smallest wall-clock time of ``repeats`` calls, seconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return min(times)


def timed(function) -> tuple[float, object]:
    """One call's wall-clock time (seconds) and its value."""
    start = time.perf_counter()
    value = function()
    return time.perf_counter() - start, value


def video_run_parser(description: str, sequence: bool = True) -> argparse.ArgumentParser:
    """A parser with the options of the streamed video-tracker benchmarks.

    ``--sequence`` (when ``sequence``; PETS09-S2L1), ``--video`` (vtest.avi), ``--frames``
    (0: all) and ``--repeats`` (timed runs after the first); a script adds its own.
    """
    parser = argparse.ArgumentParser(description=description)
    if sequence:
        parser.add_argument("--sequence", type=Path, default=DATA / "mot15" / "PETS09-S2L1")
    parser.add_argument("--video", type=Path, default=DATA / "video" / "vtest.avi")
    parser.add_argument("--frames", type=int, default=0, help="frames tracked (0: all)")
    parser.add_argument("--repeats", type=int, default=2, help="timed runs after the first")
    return parser


def add_cpu_threads_option(parser: argparse.ArgumentParser) -> None:
    """``--cpu-threads N``: XLA's CPU thread pool, as the ``jaxtrack`` command sizes it by
    default (:func:`jaxtrack.use_cpu_threads`); 0 leaves XLA's own size (one per core).
    ``--vector-width BITS``: the vector width, as the command asks for it
    (:func:`jaxtrack.use_cpu_vector_width`); 0 leaves XLA's default."""
    parser.add_argument(
        "--cpu-threads",
        type=int,
        default=DEFAULT_CPU_THREADS,
        help=f"threads of XLA's CPU pool (default {DEFAULT_CPU_THREADS}, as the jaxtrack "
        "command sets it; 0: XLA's default, one per core; PJRT_NPROC set wins)",
    )
    parser.add_argument(
        "--vector-width",
        type=int,
        choices=(0, 256, 512),
        default=DEFAULT_VECTOR_WIDTH,
        help=f"vector bits XLA's CPU code generator is asked for, with plain min/max "
        f"(default {DEFAULT_VECTOR_WIDTH}, as the jaxtrack command asks where the CPU has "
        "AVX-512; 0: XLA's defaults, 256 bits; a width in XLA_FLAGS wins)",
    )


def set_cpu_threads(count: int) -> int:
    """Applies ``--cpu-threads`` before JAX computes; returns the pool's size for the report."""
    if count > 0:
        use_cpu_threads(count)
    return cpu_thread_pool_size()


def set_cpu_vector_width(bits: int) -> int:
    """Applies ``--vector-width`` before JAX computes; returns the width in ``XLA_FLAGS`` for
    the report (0: XLA's default, 256)."""
    if bits > 0:
        use_cpu_vector_width(bits)
    return cpu_vector_width()


def phd_run_parser(description: str, repeats: int) -> argparse.ArgumentParser:
    """A parser with the options of the PHD-tracker-on-a-sequence benchmarks: ``--sequence``
    (PETS09-S2L1), ``--particles`` (2048), ``--repeats`` and ``--cpu-threads``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--sequence", type=Path, default=DATA / "mot15" / "PETS09-S2L1")
    parser.add_argument("--particles", type=int, default=2048)
    parser.add_argument("--repeats", type=int, default=repeats, help="timed runs")
    add_cpu_threads_option(parser)
    return parser


def sequence_with_phd_params(path: Path):
    """The MOT sequence at ``path`` and the PHD tracker's default parameters for it."""
    sequence = load_sequence(path)
    info = sequence.info
    return sequence, default_phd_params(info.im_width, info.im_height, info.frame_rate)
