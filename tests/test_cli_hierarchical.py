"""``jaxtrack track`` / ``track-video`` with ``--tracker hierarchical``: one synthetic walker is
one track with its event states (``RES.events.csv``), both levels drawn, ``--detections bs``,
its variants, refused options."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.io import read_mot_file, write_seqinfo
from jaxtrack.io.events import read_events
from jaxtrack.types import SequenceInfo
from tests.synthetic_video import NUM_FRAMES, SIZE, person_box, write_synthetic_folder


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    """A sequence folder with its frames (img1/) and the walker's boxes as det.txt."""
    folder = tmp_path_factory.mktemp("hier") / "Walk"
    folder.mkdir()
    write_synthetic_folder(folder / "img1")
    write_seqinfo(folder / "seqinfo.ini", SequenceInfo("Walk", NUM_FRAMES, *SIZE, 25.0))
    (folder / "det").mkdir()
    rows = [f"{k},-1,{','.join(map(str, person_box(k)))},1,-1,-1,-1" for k in range(1, 41)]
    (folder / "det" / "det.txt").write_text("\n".join(rows) + "\n")
    return folder


def test_track_writes_one_track_and_its_events(sequence, tmp_path, capsys):
    out = tmp_path / "res.txt"
    assert main(["track", str(sequence), "--tracker", "hierarchical", "--out", str(out)]) == 0
    result = read_mot_file(out, "res", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1
    assert len(result) >= NUM_FRAMES - 2  # the tentative frames are in the offline output
    events = read_events(tmp_path / "res.events.csv")
    assert sorted(zip(events.frames.tolist(), events.ids.tolist(), strict=True)) == sorted(
        zip(result.frames.tolist(), result.ids.tolist(), strict=True)
    )
    # a lone walker enters (first second), then is single; the track lasts to the end
    first = int(np.argmin(events.frames))
    assert events.names[first] == "entering"
    assert set(events.names.tolist()) <= {"entering", "single"}
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["tracker"] == "hierarchical" and used["variant"] == "full"
    assert "median of 25 frames" in used["background"]
    assert "events" in capsys.readouterr().err


@pytest.mark.parametrize("variant", ["kalman", "managed"])
def test_lower_variants_write_no_events(sequence, tmp_path, variant):
    out = tmp_path / "res.txt"
    argv = ["track", str(sequence), "--tracker", "hierarchical", "--variant", variant]
    assert main([*argv, "--out", str(out)]) == 0
    assert len(set(read_mot_file(out, "res", NUM_FRAMES).ids.tolist())) == 1
    assert not (tmp_path / "res.events.csv").exists()
    assert json.loads((tmp_path / "res.config.json").read_text())["variant"] == variant


def test_detections_by_background_subtraction(sequence, tmp_path):
    out = tmp_path / "res.txt"
    argv = ["track", str(sequence), "--tracker", "hierarchical", "--detections", "bs"]
    assert main([*argv, "--out", str(out)]) == 0
    result = read_mot_file(out, "res", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1
    truth = np.array([person_box(k) for k in result.frames], float)
    centres = result.boxes[:, :2] + result.boxes[:, 2:] / 2
    assert np.median(np.abs(centres - truth[:, :2] - truth[:, 2:] / 2)) < 4.0
    assert json.loads((tmp_path / "res.config.json").read_text())["detections"] == "bs"


def test_track_video_draws_both_levels(sequence, tmp_path):
    out = tmp_path / "res.txt"
    frames_dir = tmp_path / "annotated"
    argv = ["track-video", str(sequence / "img1"), "--tracker", "hierarchical", "--no-split"]
    argv += ["--fps", "25", "--out", str(out), "--annotate", str(frames_dir), "--quiet"]
    assert main(argv) == 0
    result = read_mot_file(out, "res", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1
    assert (tmp_path / "res.events.csv").is_file()
    last = int(result.frames.max())
    image = cv2.imread(str(frames_dir / f"{last:06d}.png"))
    x, y, _, h = result.boxes[result.frames == last][0]
    # the high-level ellipse (black) passes through the left edge's midpoint of the box
    patch = image[round(y + h / 2) - 2 : round(y + h / 2) + 3, round(x) - 2 : round(x) + 3]
    assert patch.max(axis=-1).min() < 40


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--variant", "mtb"], "--variant mtb applies to --tracker cmt"),
        (["--variant", "A1"], "A1 is a PHD context variant; hierarchical's are"),
        (["--zones", "z.json"], "--zones applies to --tracker cmt"),
    ],
)
def test_refused_options_exit_2(sequence, tmp_path, capsys, options, message):
    argv = ["track", str(sequence), "--tracker", "hierarchical", "--out", str(tmp_path / "r.txt")]
    assert main([*argv, *options]) == 2
    assert message in capsys.readouterr().err


def test_bs_detections_need_a_tracker_that_reads_frames(sequence, tmp_path, capsys):
    argv = ["track", str(sequence), "--tracker", "kalman", "--detections", "bs"]
    assert main([*argv, "--out", str(tmp_path / "r.txt")]) == 2
    assert "--detections bs needs a tracker that reads the frames" in capsys.readouterr().err
