"""Limits and the memory check: available memory (meminfo, cgroups), the error, estimators."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from jaxtrack import resources
from jaxtrack.errors import InputError
from jaxtrack.io import load_sequence, pad_detections, pad_ground_truth
from jaxtrack.resources import (
    MAX_DETECTIONS_PER_FRAME,
    ResourceError,
    available_memory_bytes,
    check_memory,
    check_rows_per_frame,
    padded_sequence_bytes,
)
from jaxtrack.types import MotTable
from tests.data import MOT15_ROOT, require_data

GB = 10**9


@pytest.fixture
def fake_linux(tmp_path, monkeypatch):
    """``/proc/meminfo``, ``/proc/self/cgroup`` and a cgroup tree under ``tmp_path``."""
    meminfo = tmp_path / "meminfo"
    meminfo.write_text("MemTotal:       24684092 kB\nMemAvailable:    8000000 kB\n")
    cgroup_file = tmp_path / "cgroup"
    root = tmp_path / "cgroup_root"
    monkeypatch.setattr(resources, "MEMINFO", meminfo)
    monkeypatch.setattr(resources, "PROC_CGROUP", cgroup_file)
    monkeypatch.setattr(resources, "CGROUP_ROOT", root)
    return meminfo, cgroup_file, root


def test_available_memory_is_meminfo_without_cgroup_limits(fake_linux):
    _, cgroup_file, root = fake_linux
    cgroup_file.write_text("0::/\n")
    root.mkdir()
    (root / "memory.max").write_text("max\n")
    assert available_memory_bytes() == 8000000 * 1024


def test_a_cgroup_v2_limit_below_meminfo_wins(fake_linux):
    _, cgroup_file, root = fake_linux
    cgroup_file.write_text("0::/job/step\n")
    leaf = root / "job" / "step"
    leaf.mkdir(parents=True)
    (leaf / "memory.max").write_text("max\n")
    (root / "job" / "memory.max").write_text(f"{3 * GB}\n")  # the parent's limit applies
    (root / "job" / "memory.current").write_text(f"{GB}\n")
    (root / "job" / "memory.stat").write_text(f"anon 1\ninactive_file {GB // 2}\n")
    # 3 GB limit, 1 GB used of which 0.5 GB reclaimable file cache.
    assert available_memory_bytes() == 3 * GB - GB // 2


def test_a_cgroup_v1_limit_below_meminfo_wins(fake_linux):
    _, cgroup_file, root = fake_linux
    cgroup_file.write_text("5:cpu,cpuacct:/\n4:memory:/box\n0::/\n")
    folder = root / "memory" / "box"
    folder.mkdir(parents=True)
    (folder / "memory.limit_in_bytes").write_text(f"{2 * GB}\n")
    (folder / "memory.usage_in_bytes").write_text(f"{GB}\n")
    (folder / "memory.stat").write_text("total_inactive_file 0\n")
    (root / "memory" / "memory.limit_in_bytes").write_text("9223372036854771712\n")  # none
    assert available_memory_bytes() == GB


def test_without_proc_the_free_pages_are_used(fake_linux):
    assert available_memory_bytes() == 8000000 * 1024  # no cgroup file: meminfo alone
    meminfo, _, _ = fake_linux
    meminfo.unlink()
    assert 0 < available_memory_bytes() <= 1 << 50  # os.sysconf's free pages


def test_the_real_machine_reports_some_memory():
    assert 2**20 < available_memory_bytes() < 2**50


def test_check_memory_names_the_need_the_machine_and_the_remedy():
    check_memory(GB, "tracking X", "--frames", available_bytes=2 * GB)
    with pytest.raises(ResourceError) as error:
        check_memory(38.5 * GB, "tracking X", "--config num_particles or --frames", 7.9 * GB)
    assert str(error.value) == (
        "tracking X needs about 38.5 GB but the machine has 7.9 GB available; lower it with "
        "--config num_particles or --frames"
    )
    assert isinstance(error.value, InputError)  # the CLI prints it on one line, exit 2


def test_check_memory_compares_with_the_machine_by_default(monkeypatch):
    monkeypatch.setattr(resources, "available_memory_bytes", lambda: 5 * GB)
    with pytest.raises(ResourceError, match=r"about 6\.0 GB but the machine has 5\.0 GB"):
        check_memory(6 * GB, "a run", "--frames")


def test_rows_per_frame_above_the_limit_name_the_file_and_the_frame():
    frames = np.concatenate([np.arange(1, 10), np.full(MAX_DETECTIONS_PER_FRAME + 1, 7)])
    check_rows_per_frame(frames[:MAX_DETECTIONS_PER_FRAME], "det.txt")
    with pytest.raises(ResourceError, match=r"^seq/det/det.txt: frame 7 has 4098 detections"):
        check_rows_per_frame(frames, "seq/det/det.txt")
    check_rows_per_frame(np.zeros(0), None)


def _allocated_bytes(function):
    """Peak bytes that ``function`` allocates (tracemalloc sees NumPy's buffers)."""
    tracemalloc.start()
    try:
        result = function()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    del result
    return peak


@pytest.mark.parametrize(("num_frames", "capacity"), [(200, 16), (1000, 300), (50, 4096)])
def test_the_padded_arrays_estimate_is_within_a_factor_two(num_frames, capacity):
    rows = min(capacity, 5) * num_frames
    table = MotTable.from_arrays(
        np.repeat(np.arange(1, num_frames + 1), rows // num_frames),
        np.arange(rows),
        np.tile([10.0, 20.0, 30.0, 60.0], (rows, 1)),
        np.ones(rows),
    )

    def pad():
        return (
            pad_detections(table, 1, num_frames, capacity),
            pad_ground_truth(table, 1, num_frames, capacity),
        )

    estimate = padded_sequence_bytes(num_frames, capacity, capacity)
    measured = _allocated_bytes(pad)
    assert estimate / 2 <= measured <= 2 * estimate
    kept = pad()
    held = sum(leaf.nbytes for part in kept for leaf in part)
    assert held == estimate  # the arrays themselves, exactly


def test_the_estimate_of_a_loaded_sequence_matches_its_arrays():
    require_data()
    sequence = load_sequence(MOT15_ROOT / "TUD-Campus")
    detections, truth = sequence.detections, sequence.ground_truth
    estimate = padded_sequence_bytes(
        sequence.num_frames, detections.mask.shape[1], truth.mask.shape[1]
    )
    assert estimate == sum(leaf.nbytes for leaf in (*detections, *truth))
