"""No command writes over its own inputs; bad outputs are refused before any work (issue 14).

Each refused run exits 2 with one error line naming the option, leaves every input byte for
byte as it was and writes nothing (tests/cli_workspace.py). Valid outputs into new nested
folders are still written.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from typing import NamedTuple

import pytest
from matplotlib.image import imread

from jaxtrack.cli import main
from jaxtrack.commands import tune as tune_command
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.io import read_mot_file
from tests.cli_workspace import run_refused, snapshot
from tests.data import REPO_ROOT
from tests.synthetic_video import write_synthetic_folder


class TuningResult(NamedTuple):
    """What ``tune_sequence`` returns, as far as ``jaxtrack tune`` reads it."""

    config: PHDConfig
    report: dict


#: ``(arguments, what the error line says)``; ``{name}`` fields are workspace paths.
REFUSED = [
    # track, one sequence
    (
        "track {seq} --out {seq}/det/det.txt",
        "--out {seq}/det/det.txt is an input of this run (the detections of {seq})",
    ),
    (
        "track {seq} --out {seq}/det/../gt/gt.txt",
        "--out {seq}/det/../gt/gt.txt is an input of this run (the ground truth of {seq})",
    ),
    (
        "track {seq} --out {tmp}/link.txt",
        "--out {tmp}/link.txt is an input of this run (the sequence information of {seq})",
    ),
    (
        "track {seq} --out {tmp}/hard.txt",
        "--out {tmp}/hard.txt is an input of this run (the detections of {seq})",
    ),
    (
        "track {seq} --out {tmp}/run.txt --config {config}",
        "{config} (written with --out {tmp}/run.txt) is an input of this run "
        "(the tracker configuration --config {config})",
    ),
    (
        "track {seq} --out {config} --config {config}",
        "--out {config} is an input of this run (the tracker configuration --config {config})",
    ),
    (
        "track {seq} --out {ctx} --context {ctx}",
        "--out {ctx} is an input of this run (the context --context {ctx})",
    ),
    (
        "track {seq} --out {seq}/TUD-Campus.mp4",
        "--out {seq}/TUD-Campus.mp4 is an input of this run (the video of {seq})",
    ),
    (
        "track {seq} --out {tmp}/r.txt --figure {seq}/img1/000001.png",
        "--figure {seq}/img1/000001.png is an input of this run (the frames of {seq})",
    ),
    (
        "track {seq} --out {tmp}/r.txt --figure {seq}/img1/new.png",
        "--figure {seq}/img1/new.png would add a frame to {seq}/img1, an input of this run",
    ),
    (
        "track {seq} --out {tmp}/r.txt --figure {tmp}/f.png --video {tmp}/f.png",
        "--figure {tmp}/f.png is an input of this run (the frames --video {tmp}/f.png)",
    ),
    (
        "track {seq} --out {tmp}/folder",
        "--out {tmp}/folder is a folder; give a file path",
    ),
    (
        "track {seq} --out {tmp}/r.png --figure {tmp}/r.png",
        "--out {tmp}/r.png and --figure {tmp}/r.png are the same path",
    ),
    (
        "track {seq} --out {tmp}/r.txt --figure {tmp}/r.txt/f.png",
        "--figure {tmp}/r.txt/f.png lies inside --out {tmp}/r.txt, a file this run writes",
    ),
    (
        "track {seq} --out {tmp}/file.txt/r.txt",
        "--out {tmp}/file.txt/r.txt cannot be written: {tmp}/file.txt is not a folder",
    ),
    (
        "track {seq} --out {tmp}/r.txt --figure {tmp}/f.txt",
        "--figure {tmp}/f.txt: matplotlib writes no .txt figures",
    ),
    # track --benchmark
    (
        "track --benchmark {mot} --out {tmp}/file.txt",
        "--out {tmp}/file.txt exists and is not a folder",
    ),
    (
        "track --benchmark {mot} --out {mot}",
        "--out {mot} is an input of this run (the sequences of {mot})",
    ),
    # track-video
    (
        "track-video {frames} --out {frames}/000001.png",
        "--out {frames}/000001.png is an input of this run (the video {frames})",
    ),
    (
        "track-video {frames} --out {tmp}/r.txt --annotate {frames}",
        "--annotate {frames} is an input of this run (the video {frames})",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --annotate {video}",
        "--annotate {video} is an input of this run (the video {video})",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --save-detections {tmp}/folder",
        "--save-detections {tmp}/folder is a folder; give a file path",
    ),
    (
        "track-video {video} --out {tmp}/d.txt --save-detections {tmp}/d.txt",
        "--out {tmp}/d.txt and --save-detections {tmp}/d.txt are the same path",
    ),
    (
        "track-video {video} --out {seq}/det/det.txt --detections {seq}/det/det.txt",
        "--out {seq}/det/det.txt is an input of this run (the detections --detections",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --gt {tmp}/r.config.json",
        "{tmp}/r.config.json (written with --out {tmp}/r.txt) is an input of this run "
        "(the ground truth --gt {tmp}/r.config.json)",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --annotate {tmp}/a --gt {tmp}/a/000002.png",
        "--annotate {tmp}/a would write over {tmp}/a/000002.png, an input of this run",
    ),
    (
        "track-video {video} --out {tmp}/a/000001.png --annotate {tmp}/a",
        "--out {tmp}/a/000001.png would be overwritten by the frames of --annotate {tmp}/a",
    ),
    # detect
    (
        "detect {frames} --out {frames}/000001.png",
        "--out {frames}/000001.png is an input of this run (the video {frames})",
    ),
    (
        "detect {frames} --out {frames}/new.jpg",
        "--out {frames}/new.jpg would add a frame to {frames}, an input of this run",
    ),
    (
        "detect {frames} --out {tmp}/folder",
        "--out {tmp}/folder is a folder; give a file path",
    ),
    (
        "detect {video} --out {tmp}/d.txt --preview {video}",
        "--preview {video} is an input of this run (the video {video})",
    ),
    (
        "detect {frames} --out {tmp}/d.txt --preview {frames}",
        "--preview {frames} is an input of this run (the video {frames})",
    ),
    (
        "detect {video} --out {tmp}/d.txt --gt {tmp}/d.txt",
        "--out {tmp}/d.txt is an input of this run (the ground truth --gt {tmp}/d.txt)",
    ),
    # learn-context
    (
        "learn-context {seq} --out {seq}/gt/gt.txt",
        "--out {seq}/gt/gt.txt is an input of this run (the ground truth of {seq})",
    ),
    (
        "learn-context {seq} --out {tmp}/folder",
        "--out {tmp}/folder is a folder; give a file path",
    ),
    (
        "learn-context {seq} --out {tmp}/c.npz --plot {seq}/img1",
        "--plot {seq}/img1 is an input of this run (the frames of {seq})",
    ),
    (
        "learn-context {seq} --out {seq}/img1/c.png",
        "--out {seq}/img1/c.png would add a frame to {seq}/img1, an input of this run "
        "(the frames of {seq})",
    ),
    (
        "learn-context {seq} --out {tmp}/p/intensities.png --plot {tmp}/p",
        "--out {tmp}/p/intensities.png and {tmp}/p/intensities.png (written with --plot "
        "{tmp}/p) are the same path",
    ),
    (
        "learn-context {seq} --out {tmp}/c.npz --plot {tmp}/file.txt",
        "--plot {tmp}/file.txt exists and is not a folder",
    ),
    (
        "learn-context {seq} --out {tmp}/labels.json --clutter-from {tmp}/labels.json",
        "--out {tmp}/labels.json is an input of this run (the clutter labels --clutter-from",
    ),
    (
        "learn-context {video} --detections {seq}/det/det.txt --out {seq}/det/det.txt",
        "--out {seq}/det/det.txt is an input of this run (the detections --detections",
    ),
    # label-clutter
    (
        "label-clutter {seq} --frames 1:5 --out {seq}/det/det.txt",
        "--out {seq}/det/det.txt is an input of this run (the detections of {seq})",
    ),
    (
        "label-clutter {seq} --frames 1:5 --out {tmp}/folder",
        "--out {tmp}/folder is a folder; give a file path",
    ),
    (
        "label-clutter {seq} --out {tmp}/l.json --resume {tmp}/labels.json --video {tmp}/l.json",
        "--out {tmp}/l.json is an input of this run (the frames --video {tmp}/l.json)",
    ),
    # simulate
    ("simulate --out {tmp}/file.txt", "--out {tmp}/file.txt exists and is not a folder"),
    (
        "simulate --out {seq}",
        "--out {seq} holds a sequence that jaxtrack simulate did not write (no "
        "context_truth.npz); its seqinfo.ini, det/det.txt and gt/gt.txt would be overwritten: "
        "give another folder",
    ),
    (
        "simulate --out {tmp}/file.txt/scene",
        "--out {tmp}/file.txt/scene cannot be written: {tmp}/file.txt is not a folder",
    ),
    # tune
    (
        "tune {seq} --out {tmp}/t.json --config {tmp}/t.tuning.json",
        "{tmp}/t.tuning.json (written with --out {tmp}/t.json) is an input of this run "
        "(the tracker configuration --config {tmp}/t.tuning.json)",
    ),
    (
        "tune {seq} --out {seq}/gt/gt.json --config {seq}/gt/gt.json",
        "--out {seq}/gt/gt.json is an input of this run (the tracker configuration",
    ),
    (
        "tune {seq} --out {tmp}/file.txt/t.json",
        "--out {tmp}/file.txt/t.json cannot be written: {tmp}/file.txt is not a folder",
    ),
    (
        "tune {seq} --context {ctx} --out {ctx}",
        "--out {ctx} is an input of this run (the context --context {ctx})",
    ),
    (
        "tune {seq} --context {ctx} --out {tmp}/t.npz --config {tmp}/t.config.json",
        "{tmp}/t.config.json (written with --out {tmp}/t.npz) is an input of this run "
        "(the tracker configuration --config {tmp}/t.config.json)",
    ),
    # demo
    ("demo --out {tmp}/file.txt", "--out {tmp}/file.txt exists and is not a folder"),
    (
        "demo --out {tmp}/file.txt/demo",
        "--out {tmp}/file.txt/demo cannot be written: {tmp}/file.txt is not a folder",
    ),
    # experiments
    (
        "experiment context-ablation --out {tmp}/file.txt --sequence {seq}",
        "--out {tmp}/file.txt exists and is not a folder",
    ),
    (
        "experiment compare-trackers --out {mot} --mot-root {mot}",
        "--out {mot} is an input of this run (the sequences of {mot})",
    ),
    (
        "experiment gradient-tuning --out {tmp}/g --pets {tmp}/g/synthetic",
        "{tmp}/g/synthetic/seqinfo.ini (written with --out {tmp}/g) is an input of this run "
        "(the sequence information of {tmp}/g/synthetic)",
    ),
]


@pytest.mark.parametrize(("arguments", "message"), REFUSED)
def test_bad_output_is_refused_before_any_work(workspace, tmp_path, capsys, arguments, message):
    argv = arguments.format(**workspace).split()
    line = run_refused(capsys, tmp_path, argv)
    assert message.format(**workspace) in line


#: ``(arguments, a file to write first, what the error line says)``.
REFUSED_WITH_A_FILE = [
    (
        "track --benchmark {mot} --out {tmp}/res --config {tmp}/res/S1.config.json",
        "res/S1.config.json",
        "{tmp}/res/S1.config.json (written with --out {tmp}/res) is an input of this run "
        "(the tracker configuration --config {tmp}/res/S1.config.json)",
    ),
    (
        "simulate --out {tmp}/sim --scene-config {tmp}/sim/seqinfo.ini",
        "sim/seqinfo.ini",
        "{tmp}/sim/seqinfo.ini (written with --out {tmp}/sim) is an input of this run "
        "(the scene configuration {tmp}/sim/seqinfo.ini)",
    ),
    (
        "tune {seq} --out {tmp}/t.json",
        "t.json/inside.txt",
        "--out {tmp}/t.json is a folder; give a file path",
    ),
    (
        "demo --out {tmp}/demo",
        "demo/demo.png/inside.txt",
        "{tmp}/demo/demo.png (written with --out {tmp}/demo) is a folder; give a file path",
    ),
    (
        "experiment context-ablation --out {tmp}/abl",
        "abl/scene/det/det.txt/inside.txt",
        "{tmp}/abl/scene/det/det.txt (written with --out {tmp}/abl) is a folder",
    ),
]


@pytest.mark.parametrize(("arguments", "existing", "message"), REFUSED_WITH_A_FILE)
def test_bad_output_is_refused_given_an_existing_file(
    workspace, tmp_path, capsys, arguments, existing, message
):
    """A tracker configuration (or scene configuration) is valid JSON: `{}`."""
    (tmp_path / existing).parent.mkdir(parents=True, exist_ok=True)
    (tmp_path / existing).write_text("{}")
    argv = arguments.format(**workspace).split()
    line = run_refused(capsys, tmp_path, argv)
    assert message.format(**workspace) in line


def test_write_over_a_frame_is_refused_in_a_fresh_process(workspace, tmp_path):
    """The reproduction of issue 14 as a user runs it: `jaxtrack detect IMGDIR --out
    IMGDIR/000001.png` used to overwrite a frame."""
    frames = workspace["frames"]
    before = snapshot(tmp_path)
    result = subprocess.run(
        [sys.executable, "-m", "jaxtrack", "detect", frames, "--out", f"{frames}/000001.png"],
        capture_output=True,
        text=True,
        cwd=REPO_ROOT,
        timeout=300,
    )
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        f"jaxtrack detect: error: --out {frames}/000001.png is an input of this run "
        f"(the video {frames})"
    ]
    assert snapshot(tmp_path) == before


def test_unwritable_output_is_refused(workspace, tmp_path, capsys, monkeypatch):
    """Runs as root see every folder writable, so os.access is made to say no."""
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access

    def access(path, mode):
        return False if os.path.realpath(path).startswith(str(locked)) else real_access(path, mode)

    monkeypatch.setattr(os, "access", access)
    seq = workspace["seq"]
    line = run_refused(capsys, tmp_path, ["track", seq, "--out", f"{locked}/new/r.txt"])
    assert f"--out {locked}/new/r.txt cannot be written: {locked} is not writable" in line
    (locked / "r.txt").write_text("old\n")
    line = run_refused(capsys, tmp_path, ["detect", seq, "--out", f"{locked}/r.txt"])
    assert f"--out {locked}/r.txt is not writable" in line


def test_label_clutter_resume_may_continue_its_own_file(workspace, tmp_path, capsys):
    """--resume X --out X updates the labels file in place: not refused as an input."""
    labels = tmp_path / "labels.json"
    argv = ["label-clutter", workspace["seq"], "--resume", str(labels), "--out", str(labels)]
    line = run_refused(capsys, tmp_path, argv)  # refused later, for the empty labels file
    assert "is an input" not in line and str(labels) in line


def test_valid_outputs_into_new_nested_folders_are_written(workspace, tmp_path, capsys):
    """Outputs are refused for what they overwrite, not for where they are: new files in new
    folders inside a sequence folder are written, and its inputs stay as they were."""
    seq = workspace["seq"]
    small = tmp_path / "small.json"
    small.write_text(json.dumps({"num_particles": 64, "births_per_detection": 4}))
    inputs = snapshot(tmp_path / "mot")
    out = tmp_path / "mot" / "S1" / "det" / "a" / "r.txt"
    figure = tmp_path / "new" / "b" / "frame"  # matplotlib adds .png
    argv = ["track", seq, "--frames", "1:4", "--config", str(small), "--out", str(out)]
    assert main([*argv, "--figure", str(figure)]) == 0, capsys.readouterr().err
    result = read_mot_file(out, "res")
    assert set(result.frames.tolist()) <= {1, 2, 3, 4}
    used = json.loads((out.parent / "r.config.json").read_text())
    assert used["variant"] == "UM" and used["frames"] == [1, 4] and used["num_particles"] == 64
    assert imread(f"{figure}.png").ndim == 3
    assert {k: v for k, v in snapshot(tmp_path / "mot").items() if "det/a" not in k} == inputs

    frames = write_synthetic_folder(tmp_path / "walker")
    det = tmp_path / "new" / "c" / "det.txt"
    preview = tmp_path / "new" / "d" / "preview"
    argv = ["detect", str(frames), "--frames", "1:5", "--no-split", "--out", str(det)]
    assert main([*argv, "--preview", str(preview), "--quiet"]) == 0
    assert set(read_mot_file(det, "det").frames.tolist()) == {1, 2, 3, 4, 5}
    assert sorted(p.name for p in preview.iterdir()) == [f"{k:06d}.png" for k in range(1, 6)]

    scene = tmp_path / "new" / "e" / "scene"
    assert main(["simulate", "--out", str(scene), "--num-frames", "20"]) == 0
    assert read_mot_file(scene / "gt" / "gt.txt", "gt").frames.max() <= 20
    capsys.readouterr()


def test_tune_creates_the_folder_of_its_output(workspace, tmp_path, capsys, monkeypatch):
    """The tuning itself is replaced (tests/test_cli_tune.py runs it): what is written where."""
    tuned = PHDConfig(clutter_rate=0.5)
    report = {"objective": "likelihood", "tuned": {"clutter_rate": 0.5}}
    monkeypatch.setattr(
        tune_command, "tune_sequence", lambda *args, **kwargs: TuningResult(tuned, report)
    )
    out = tmp_path / "new" / "tuned.json"
    assert main(["tune", workspace["seq"], "--frames", "1:10", "--out", str(out), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["out"] == str(out)
    assert json.loads(out.read_text()) == {"clutter_rate": 0.5}
    assert json.loads((tmp_path / "new" / "tuned.tuning.json").read_text()) == report
