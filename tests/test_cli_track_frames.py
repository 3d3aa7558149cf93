"""``jaxtrack track --tracker NAME`` for a tracker that uses frames: the frames found (or
``--video``), checked against ``seqinfo.ini``, streamed through the tracker; ``--detections``.

The tracker is the test-only mean-colour filter (tests/filters/frame_filters.py), registered
for each test: its result rows are the detections, scored with the mean red under each box,
which the tests compare with the frames read directly.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.filters.registry import TRACKERS
from jaxtrack.io import read_mot_file, write_seqinfo
from jaxtrack.types import SequenceInfo
from tests.cli_workspace import run_refused
from tests.filters.frame_filters import MEAN_COLOUR_ENTRY, numpy_mean_colours
from tests.synthetic_video import NUM_FRAMES, SIZE, person_box, write_synthetic_folder

NAME = "Walk"


@pytest.fixture(autouse=True)
def mean_colour_tracker(monkeypatch):
    monkeypatch.setitem(TRACKERS, "mean-colour", MEAN_COLOUR_ENTRY)


@pytest.fixture
def sequence(tmp_path) -> Path:
    """A sequence folder: seqinfo.ini, img1/ (a walking rectangle), det/det.txt (the
    rectangle's box, and a box on the background in odd frames)."""
    folder = tmp_path / NAME
    folder.mkdir()
    write_synthetic_folder(folder / "img1")
    write_seqinfo(folder / "seqinfo.ini", SequenceInfo(NAME, NUM_FRAMES, *SIZE, 25.0))
    (folder / "det").mkdir()
    rows = [f"{k},-1,{','.join(map(str, person_box(k)))},1,-1,-1,-1" for k in range(1, 41)]
    rows += [f"{k},-1,150.5,10.25,30,20.5,0.5,-1,-1,-1" for k in range(1, 41, 2)]
    (folder / "det" / "det.txt").write_text("\n".join(rows) + "\n")
    return folder


def frames_of(folder: Path) -> list[np.ndarray]:
    """The RGB frames of an image folder, read directly (not through jaxtrack)."""
    paths = sorted(folder.glob("*.png"))
    return [cv2.cvtColor(cv2.imread(str(p)), cv2.COLOR_BGR2RGB) for p in paths]


def write_avi(path: Path, frames: list[np.ndarray]) -> Path:
    """The frames as a lossless (FFV1) video."""
    height, width = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), 25.0, (width, height))
    for frame in frames:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    writer.release()
    return path


def check_mean_colours(result_path: Path, frames: list[np.ndarray], detections) -> None:
    """The result rows are the detections, each scored with the mean red under its box."""
    result = read_mot_file(result_path, "res")
    order = np.lexsort((*detections.boxes.T[::-1], detections.frames))
    found = np.lexsort((*result.boxes.T[::-1], result.frames))
    np.testing.assert_array_equal(result.frames[found], detections.frames[order])
    np.testing.assert_allclose(result.boxes[found], detections.boxes[order], rtol=1e-6)
    for row in range(len(result)):
        image = frames[result.frames[row] - 1]
        red = numpy_mean_colours(image, result.boxes[row : row + 1])[0, 0]
        assert result.confs[row] == pytest.approx(red, rel=1e-5)


def test_frames_from_img1_are_streamed_through_the_tracker(sequence, tmp_path, capsys):
    out = tmp_path / "res.txt"
    argv = ["track", str(sequence), "--tracker", "mean-colour", "--frames", "3:37"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 35
    detections = read_mot_file(sequence / "det" / "det.txt", "det").frame_span(3, 37)
    frames = frames_of(sequence / "img1")
    check_mean_colours(out, frames, detections)
    # The walking rectangle is a uniform colour: its mean is that colour exactly.
    result = read_mot_file(out, "res")
    rectangle = result.confs[result.boxes[:, 3] == 32]
    np.testing.assert_allclose(rectangle, frames[0][60, 10, 0])
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["tracker"] == "mean-colour" and used["video"] == str(sequence / "img1")
    assert used["frames"] == [3, 37]


def test_a_video_in_the_folder_or_given_with_video(sequence, tmp_path):
    frames = frames_of(sequence / "img1")
    detections = read_mot_file(sequence / "det" / "det.txt", "det")
    shutil.rmtree(sequence / "img1")
    write_avi(sequence / f"{NAME}.avi", frames)
    out = tmp_path / "found.txt"
    assert main(["track", str(sequence), "--tracker", "mean-colour", "--out", str(out)]) == 0
    check_mean_colours(out, frames, detections)
    # --video: frames elsewhere (here, upside down) take the place of the folder's.
    flipped = [np.ascontiguousarray(frame[::-1]) for frame in frames]
    video = write_avi(tmp_path / "flipped.avi", flipped)
    out = tmp_path / "given.txt"
    argv = ["track", str(sequence), "--tracker", "mean-colour", "--video", str(video)]
    assert main([*argv, "--out", str(out)]) == 0
    check_mean_colours(out, flipped, detections)
    assert json.loads((tmp_path / "given.config.json").read_text())["video"] == str(video)


def test_detections_from_jaxtrack_detect(sequence, tmp_path):
    det = tmp_path / "bgs.txt"
    assert main(["detect", str(sequence / "img1"), "--out", str(det), "--no-split", "--quiet"]) == 0
    detections = read_mot_file(det, "det")
    assert len(detections) >= 30  # the walking rectangle, found by background subtraction
    out = tmp_path / "res.txt"
    argv = ["track", str(sequence), "--tracker", "mean-colour", "--detections", str(det)]
    assert main([*argv, "--out", str(out)]) == 0
    check_mean_colours(out, frames_of(sequence / "img1"), detections)
    assert json.loads((tmp_path / "res.config.json").read_text())["detections"] == str(det)


def test_benchmark_streams_each_sequence(sequence, tmp_path):
    single = tmp_path / "single.txt"
    assert main(["track", str(sequence), "--tracker", "mean-colour", "--out", str(single)]) == 0
    argv = ["track", "--benchmark", str(tmp_path), "--tracker", "mean-colour", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "all")]) == 0
    assert (tmp_path / "all" / f"{NAME}.txt").read_text() == single.read_text()


def test_missing_or_mismatched_frames_are_named(sequence, tmp_path, capsys):
    frames = frames_of(sequence / "img1")
    short = write_avi(tmp_path / "short.avi", frames[:20])
    argv = ["track", str(sequence), "--tracker", "mean-colour", "--out", str(tmp_path / "r.txt")]
    line = run_refused(capsys, tmp_path, [*argv, "--video", str(short)])
    assert f"{short}: holds 20 frames of 240x120 but {NAME}'s seqinfo.ini says 40" in line
    small = write_avi(tmp_path / "small.avi", [frame[:, :200] for frame in frames])
    line = run_refused(capsys, tmp_path, [*argv, "--video", str(small)])
    assert "holds 40 frames of 200x120 but" in line and "40 frames of 240x120" in line
    shutil.rmtree(sequence / "img1")
    line = run_refused(capsys, tmp_path, argv)
    assert f"no frames for {sequence}: looked for {sequence / 'img1'}/ and" in line
    assert f"{NAME}.mp4" in line and f"{NAME}.avi" in line and "(--video)" in line


def test_video_without_figure_is_refused_for_a_tracker_without_frames(sequence, tmp_path, capsys):
    argv = ["track", str(sequence), "--out", str(tmp_path / "r.txt"), "--tracker", "kalman"]
    line = run_refused(capsys, tmp_path, [*argv, "--video", str(sequence / "img1")])
    assert "--video needs --figure (the kalman tracker reads no frames)" in line
    argv = ["track", "--benchmark", str(tmp_path), "--out", str(tmp_path / "all")]
    line = run_refused(capsys, tmp_path, [*argv, "--detections", str(tmp_path / "d.txt")])
    assert "--detections applies to one sequence, not to --benchmark" in line


def test_detections_option_for_a_tracker_without_frames(mot15_root, tmp_path):
    """--detections naming the folder's own det.txt gives the same results as without."""
    campus = mot15_root / "TUD-Campus"
    argv = ["track", str(campus), "--tracker", "kalman", "--frames", "5:40"]
    assert main([*argv, "--out", str(tmp_path / "own.txt")]) == 0
    det = str(campus / "det" / "det.txt")
    assert main([*argv, "--detections", det, "--out", str(tmp_path / "given.txt")]) == 0
    own = (tmp_path / "own.txt").read_text()
    assert own and (tmp_path / "given.txt").read_text() == own
