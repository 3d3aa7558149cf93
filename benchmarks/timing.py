"""Wall-clock timing shared by the benchmark scripts (imported as ``timing``: a script's
own folder is first on ``sys.path``)."""

from __future__ import annotations

import argparse
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
