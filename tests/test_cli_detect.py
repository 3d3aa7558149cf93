"""``jaxtrack detect``: output format on a synthetic image folder, preview, bad videos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.io import read_mot_file
from tests.synthetic_video import NUM_FRAMES, person_box, write_synthetic_folder


@pytest.fixture(scope="module")
def synthetic_folder(tmp_path_factory) -> Path:
    return write_synthetic_folder(tmp_path_factory.mktemp("video") / "img1")


@pytest.mark.parametrize("method", ["horprasert", "mog2"])
def test_detect_writes_one_box_per_frame_on_the_person(synthetic_folder, tmp_path, method):
    out = tmp_path / "det.txt"
    preview = tmp_path / "preview"
    code = main(
        [
            "detect", str(synthetic_folder), "--method", method, "--out", str(out),
            "--frames", "3:40", "--preview", str(preview), "--no-split",
        ]
    )  # fmt: skip
    assert code == 0
    table = read_mot_file(out, "det", NUM_FRAMES)
    assert np.all(table.ids == -1)
    assert len(np.unique(table.frames)) == len(table)  # at most one box per frame
    assert set(table.frames.tolist()) <= set(range(3, 41))  # numbered from 1, in the span
    # MOG2 keeps adapting after its short warm-up and may miss a frame; Horprasert may not
    assert len(table) >= (38 if method == "horprasert" else 35)
    truth = np.array([person_box(k) for k in table.frames], float)
    # masks are made at half resolution: edges may move by a pixel there (2 here)
    np.testing.assert_allclose(table.boxes[:, 1], truth[:, 1], atol=4)
    np.testing.assert_allclose(table.boxes[:, 3], truth[:, 3], atol=8)
    centres = table.boxes[:, 0] + table.boxes[:, 2] / 2
    np.testing.assert_allclose(centres, truth[:, 0] + truth[:, 2] / 2, atol=1.5)
    assert np.all(_iou(table.boxes, truth) > 0.7)
    assert len(list(preview.glob("*.png"))) == 38


def _iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise IoU of ``(x, y, w, h)`` boxes."""
    width = np.minimum(a[:, 0] + a[:, 2], b[:, 0] + b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    height = np.minimum(a[:, 1] + a[:, 3], b[:, 1] + b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    inter = np.clip(width, 0, None) * np.clip(height, 0, None)
    return inter / (a[:, 2] * a[:, 3] + b[:, 2] * b[:, 3] - inter)


def test_corrupt_video_exits_2_naming_the_file(tmp_path, capsys):
    bad = tmp_path / "broken.avi"
    bad.write_bytes(b"RIFF\x00\x00\x00\x00AVI garbage" * 50)
    assert main(["detect", str(bad), "--out", str(tmp_path / "d.txt")]) == 2
    err = capsys.readouterr().err
    assert "jaxtrack detect: error:" in err and str(bad) in err and "Traceback" not in err
    assert not (tmp_path / "d.txt").exists()


def test_missing_video_exits_2(tmp_path, capsys):
    missing = tmp_path / "nope.mp4"
    assert main(["detect", str(missing), "--out", str(tmp_path / "d.txt")]) == 2
    assert str(missing) in capsys.readouterr().err


def test_truncated_video_exits_2(tmp_path, data_root, capsys):
    """The first 300 kB of vtest.avi: opens, but frames beyond the cut do not decode."""
    cut = tmp_path / "cut.avi"
    cut.write_bytes((data_root / "video" / "vtest.avi").read_bytes()[:300_000])
    code = main(["detect", str(cut), "--out", str(tmp_path / "d.txt"), "--frames", "1:795"])
    assert code == 2
    err = capsys.readouterr().err
    assert str(cut) in err and "Traceback" not in err


def test_bad_frame_span_exits_2(synthetic_folder, tmp_path, capsys):
    code = main(["detect", str(synthetic_folder), "--frames", "5:99", "--out", str(tmp_path / "d")])
    assert code == 2
    assert "frame span" in capsys.readouterr().err
