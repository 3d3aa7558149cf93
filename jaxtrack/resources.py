"""Documented size limits and the up-front memory check (base layer).

Sizes that come from the input (frames, detections per frame, particles, births, track ids)
decide how much memory a run takes. They are checked before anything is allocated:

* a size above its limit (the table below) is an :class:`~jaxtrack.errors.InputError`
  naming the file or option, whatever the machine;
* the estimated peak memory of a run (``memory`` in the tracker registry; the host arrays
  of a sequence, :func:`padded_sequence_bytes`) is compared with the memory the machine has
  (:func:`available_memory_bytes`) by :func:`check_memory`, which raises a
  :class:`ResourceError` saying how much is needed and which option lowers it.

Limits (each is a module constant; the rationale is in its comment):

======================================  =========  ===========================================
size                                    limit      where it is enforced
======================================  =========  ===========================================
frames of a sequence (``seqLength``)    10^6       ``seqinfo.ini`` (:mod:`jaxtrack.io`)
detections per frame                    4096       :func:`check_rows_per_frame` (file, frame)
particles (``num_particles``)           2^20       PHD configuration
births per detection                    1024       PHD configuration
simultaneous synthetic targets          1000       :mod:`jaxtrack.datasets.synthetic`
======================================  =========  ===========================================
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import NamedTuple

import numpy as np

from jaxtrack.errors import InputError
from jaxtrack.limits import MAX_DETECTIONS_PER_FRAME, MAX_FRAMES

__all__ = ["MAX_DETECTIONS_PER_FRAME", "MAX_FRAMES"]  # the limits, re-exported beside the checks

#: Bytes per padded slot of :class:`~jaxtrack.types.Detections` (float32 box and score,
#: bool mask) and of :class:`~jaxtrack.types.GroundTruth` (float32 box, int32 id, two bools).
DETECTION_SLOT_BYTES = 4 * 4 + 4 + 1
GROUND_TRUTH_SLOT_BYTES = 4 * 4 + 4 + 1 + 1

#: Where Linux reports the memory available to new allocations, and the cgroup hierarchy
#: whose memory limits (v2 ``memory.max``, v1 ``memory.limit_in_bytes``) may be lower.
MEMINFO = Path("/proc/meminfo")
PROC_CGROUP = Path("/proc/self/cgroup")
CGROUP_ROOT = Path("/sys/fs/cgroup")
#: A cgroup limit at least this large means "no limit" (v1 writes 2^63 rounded to a page).
_NO_LIMIT = 1 << 60
_GB = 1e9


class ResourceError(InputError):
    """A run would need more memory than the machine has (or a size above its limit)."""


class MemoryEstimate(NamedTuple):
    """A tracker run's memory, estimated from its sizes without compiling (registry ``memory``).

    Attributes:
        chunk_bytes: one compiled chunk call (:func:`~jaxtrack.filters.base.run` with
            ``chunk_frames``) on the device: its arguments (state, params, the chunk's padded
            detections), outputs (state, the chunk's per-frame outputs) and XLA's temporary
            buffers, as ``compiled.memory_analysis()`` counts them.
        frame_output_bytes: the per-frame outputs of one frame, which a run keeps for every
            frame.
    """

    chunk_bytes: int
    frame_output_bytes: int

    def run_bytes(self, num_frames: int) -> int:
        """Peak bytes of a chunked run over ``num_frames`` frames.

        One chunk call plus every frame's outputs twice (the per-chunk outputs and their
        concatenation at the end of the run); the padded input arrays are
        :func:`padded_sequence_bytes`.
        """
        return int(self.chunk_bytes + 2 * num_frames * self.frame_output_bytes)


def available_memory_bytes() -> int:
    """Memory that new allocations of this process can take, in bytes.

    The smallest of: ``MemAvailable`` of ``/proc/meminfo`` (free memory plus reclaimable
    caches), and, for each memory cgroup of this process and its ancestors that sets a limit,
    the limit minus the cgroup's usage (less its inactive file cache, which the kernel
    reclaims first). Without ``/proc`` (not Linux), the free physical pages
    (``os.sysconf``).

    Returns:
        Available bytes (0 or more).
    """
    candidates = [value for value in (_meminfo_available(), *_cgroup_headroom()) if value >= 0]
    if not candidates:
        candidates = [_sysconf_available()]
    return max(0, min(candidates))


def check_memory(
    estimate_bytes: float, what: str, remedy: str, available_bytes: int | None = None
) -> None:
    """Refuses a run whose estimated peak memory exceeds what the machine has.

    Args:
        estimate_bytes: the estimated peak memory.
        what: what needs it, in words (e.g. ``"tracking TUD-Campus with the PHD tracker"``).
        remedy: the options that lower it (e.g. ``"--config num_particles or --frames"``).
        available_bytes: the memory to compare with; None for :func:`available_memory_bytes`.

    Raises:
        ResourceError: ``"{what} needs about X GB but the machine has Y GB available; lower
            it with {remedy}"``.
    """
    available = available_memory_bytes() if available_bytes is None else available_bytes
    if estimate_bytes > available:
        raise ResourceError(
            f"{what} needs about {_gigabytes(estimate_bytes)} GB but the machine has "
            f"{_gigabytes(available)} GB available; lower it with {remedy}"
        )


def padded_sequence_bytes(num_frames: int, max_detections: int, max_objects: int = 0) -> int:
    """Host bytes of a sequence's padded arrays (:func:`jaxtrack.io.load_sequence`).

    ``num_frames x (max_detections x DETECTION_SLOT_BYTES + max_objects x
    GROUND_TRUTH_SLOT_BYTES)``: the padded detections and, with ``max_objects`` > 0, the
    padded ground truth. Checked before padding, it refuses a sequence whose arrays would not
    fit (e.g. a million frames padded to one crowded frame's count).

    Args:
        num_frames: frames of the span.
        max_detections: detection capacity (the largest count of a frame).
        max_objects: ground-truth capacity (0 without ground truth).

    Returns:
        The bytes.
    """
    per_frame = max_detections * DETECTION_SLOT_BYTES + max_objects * GROUND_TRUTH_SLOT_BYTES
    return int(num_frames) * int(per_frame)


def check_rows_per_frame(
    frames: np.ndarray,
    source: str | os.PathLike | None,
    what: str = "detections",
    limit: int = MAX_DETECTIONS_PER_FRAME,
    lines: np.ndarray | None = None,
) -> None:
    """Refuses a table with more than ``limit`` rows in one frame.

    Args:
        frames: the frame number of each row.
        source: the file the rows came from (named in the message), or None.
        what: what the rows are, in words.
        limit: the most rows a frame may hold.
        lines: the line of each row in ``source``; the message then names the line of the
            frame's first row above the limit.

    Raises:
        ResourceError: ``"{source}[, line L]: frame F has N {what}, above the limit of L per
            frame"``, naming the first frame with the most rows.
    """
    frames = np.asarray(frames, np.int64)
    if frames.size == 0:
        return
    values, counts = np.unique(frames, return_counts=True)
    worst = int(np.argmax(counts))
    if counts[worst] > limit:
        where = f"{os.fspath(source)}: " if source is not None else ""
        if source is not None and lines is not None:
            line = np.asarray(lines)[np.flatnonzero(frames == values[worst])[limit]]
            where = f"{os.fspath(source)}, line {int(line)}: "
        raise ResourceError(
            f"{where}frame {values[worst]} has {counts[worst]} {what}, above the limit of "
            f"{limit} per frame (jaxtrack.limits.MAX_DETECTIONS_PER_FRAME); keep fewer "
            "rows per frame (e.g. drop low-score detections)"
        )


def _gigabytes(num_bytes: float) -> str:
    """Bytes as GB with two significant digits at least (``38.5``, ``0.12``)."""
    value = num_bytes / _GB
    return f"{value:.1f}" if value >= 1 else f"{value:.2g}"


def _meminfo_available() -> int:
    """``MemAvailable`` of ``/proc/meminfo`` in bytes, or -1 when unreadable."""
    try:
        text = MEMINFO.read_text()
    except OSError:
        return -1
    for line in text.splitlines():
        name, _, value = line.partition(":")
        if name == "MemAvailable":
            fields = value.split()
            if fields and fields[0].isdigit():
                return int(fields[0]) * 1024
    return -1


def _cgroup_headroom() -> list[int]:
    """Limit minus usage of each memory cgroup of this process (and its ancestors) with one."""
    try:
        lines = PROC_CGROUP.read_text().splitlines()
    except OSError:
        return []
    headroom = []
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        hierarchy, controllers, path = parts
        if hierarchy == "0" and controllers == "":  # cgroup v2 (unified)
            base, files = CGROUP_ROOT, ("memory.max", "memory.current", "inactive_file")
        elif "memory" in controllers.split(","):  # cgroup v1
            base = CGROUP_ROOT / "memory"
            files = ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        else:
            continue
        directory = base / path.strip("/")
        for folder in (directory, *directory.parents):
            value = _cgroup_folder_headroom(folder, *files)
            if value is not None:
                headroom.append(value)
            if folder == base:
                break
    return headroom


def _cgroup_folder_headroom(folder: Path, limit_file: str, usage_file: str, inactive: str):
    """``limit - (usage - inactive file cache)`` of one cgroup folder, None without a limit."""
    limit = _read_int(folder / limit_file)
    if limit is None or limit >= _NO_LIMIT:
        return None
    usage = _read_int(folder / usage_file) or 0
    reclaimable = 0
    try:
        for line in (folder / "memory.stat").read_text().splitlines():
            name, _, value = line.partition(" ")
            if name == inactive and value.strip().isdigit():
                reclaimable = int(value)
    except OSError:
        pass
    return limit - max(0, usage - reclaimable)


def _read_int(path: Path) -> int | None:
    """The integer in a one-line file (None for ``max``, a missing or unreadable file)."""
    try:
        text = path.read_text().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def _sysconf_available() -> int:
    """Free physical memory from ``os.sysconf`` (0 when the platform does not say)."""
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return 0
