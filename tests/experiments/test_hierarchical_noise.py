"""``jaxtrack experiment hierarchical-noise``: the development split, the runs on detections
alone (against the filter run with real frames: the managed low level never reads them) and a
quick run through the CLI."""

from __future__ import annotations

import json
import shutil

import jax
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.errors import InputError
from jaxtrack.experiments import hierarchical_noise
from jaxtrack.experiments.cmt_ablation import VIDEO_SEQUENCES
from jaxtrack.experiments.common import environment, environment_line
from jaxtrack.experiments.hierarchical_noise import (
    SETTINGS,
    detection_rows,
    development_folders,
)
from jaxtrack.filters.base import run
from jaxtrack.filters.hierarchical_tracker import (
    HierarchicalContext,
    build_hierarchical,
    low_noise,
)
from jaxtrack.io import load_sequence
from jaxtrack.pipelines.tracking import output_rows
from jaxtrack.types import FrameInputs


def _fake_mot15(tmp_path, names):
    for name in names:
        (tmp_path / "mot15" / name / "gt").mkdir(parents=True)
        (tmp_path / "mot15" / name / "gt" / "gt.txt").write_text("")
    (tmp_path / "mot15" / "no-gt").mkdir()
    return tmp_path


def test_the_development_split_leaves_the_video_sequences_out(tmp_path):
    data = _fake_mot15(tmp_path, ["ETH-Bahnhof", "ADL-Rundle-6", *VIDEO_SEQUENCES])
    assert [p.name for p in development_folders(data)] == ["ADL-Rundle-6", "ETH-Bahnhof"]
    with pytest.raises(InputError, match="no MOT15 training sequences besides"):
        development_folders(_fake_mot15(tmp_path / "other", list(VIDEO_SEQUENCES)))


def test_rows_on_blank_frames_equal_the_rows_on_real_ones(mot15_root):
    """The managed low level's output does not depend on the frames it is given."""
    seq = load_sequence(mot15_root / "KITTI-17", frames="1:40")
    config = SETTINGS["estimated"]
    noise, line = low_noise(config, seq.detections)
    assert "estimated from" in line
    rows = detection_rows(config, seq, noise)
    rng = np.random.default_rng(0)
    shape = (seq.num_frames, seq.info.im_height, seq.info.im_width, 3)
    frames = rng.integers(0, 256, shape, dtype=np.uint8)
    background = rng.integers(0, 256, shape[1:], dtype=np.uint8)
    filt, params = build_hierarchical(config, seq.info, HierarchicalContext(background, noise))
    _, info = run(filt, jax.random.key(0), params, FrameInputs(seq.detections, frames))
    expected = output_rows(jax.device_get(info), config, seq.first_frame)
    assert len(rows.frames) > 0
    np.testing.assert_array_equal(rows.frames, expected.frames)
    np.testing.assert_array_equal(rows.ids, expected.ids)
    np.testing.assert_allclose(rows.boxes, expected.boxes)


def test_quick_run_through_the_cli(mot15_root, tmp_path, monkeypatch, capsys):
    data = tmp_path / "data"
    (data / "mot15").mkdir(parents=True)
    shutil.copytree(mot15_root / "KITTI-17", data / "mot15" / "KITTI-17")
    monkeypatch.setattr(hierarchical_noise, "QUICK_FRAMES", 30)
    out = tmp_path / "out"
    assert main(["experiment", "hierarchical-noise", "--out", str(out), "--quick", "--quiet",
                 "--data", str(data)]) == 0  # fmt: skip
    record = json.loads((out / "results.json").read_text())
    assert record["sequences"] == ["KITTI-17"]
    assert [r["setting"] for r in record["rows"]] == [*SETTINGS, "Kalman bank"]
    assert "KITTI-17" in record["estimated_noise"]
    assert record["environment"] == environment()
    assert environment_line(record["environment"]) in (out / "table.md").read_text()
    printed = capsys.readouterr().out
    assert "| estimated |" in printed and (out / "table.md").is_file()
