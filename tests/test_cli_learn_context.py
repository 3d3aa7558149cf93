"""``jaxtrack learn-context``: context file, figures and summary; event sources; bad input."""

from __future__ import annotations

import dataclasses
import shutil

import numpy as np
import pytest

from jaxtrack import cli
from jaxtrack.context.clutter_labels import ClutterLabels, save_clutter_labels
from jaxtrack.context.io import load_context, load_context_parts
from jaxtrack.datasets import SceneConfig, generate_scene
from jaxtrack.datasets.synthetic import write_scene

FRAMES = 200


@pytest.fixture
def run_cli(monkeypatch):
    """``jaxtrack.cli.main`` with only the learn-context command registered."""
    monkeypatch.setattr(cli, "COMMANDS", ("learn_context",))
    return lambda *argv: cli.main(["learn-context", *map(str, argv)])


@pytest.fixture(scope="module")
def scene():
    return generate_scene(2, dataclasses.replace(SceneConfig(), num_frames=FRAMES))


@pytest.fixture(scope="module")
def scene_dir(scene, tmp_path_factory):
    return write_scene(scene, tmp_path_factory.mktemp("cli-learn") / "SYN-2")


def test_help_explains_the_sources(run_cli, capsys):
    with pytest.raises(SystemExit) as exit_info:
        run_cli("--help")
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for option in (
        "--frames",
        "--out",
        "--birth-from",
        "--clutter-from",
        "--plot",
        "--seed",
        "--first-frame",
    ):
        assert option in text
    assert "labelled" in text and "UM tracker" in text


def test_learns_from_ground_truth_and_writes_figures(run_cli, scene_dir, tmp_path, capsys):
    out = tmp_path / "ctx.npz"
    plots = tmp_path / "plots"
    code = run_cli(
        scene_dir,
        "--frames",
        f"1:{FRAMES}",
        "--birth-from",
        "gt",
        "--out",
        out,
        "--plot",
        plots,
        "--first-frame",
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert f"wrote {out}" in printed and "birth:" in printed and "clutter:" in printed
    birth, clutter, meta = load_context(out)
    assert birth.dim == 6 and clutter.dim == 4
    assert meta["birth"]["source"] == "gt" and meta["clutter"]["source"] == "gt"
    assert meta["frames"] == [1, FRAMES]
    lam_r = meta["clutter"]["magnitude"]
    counted = meta["clutter"]["num_events"] / meta["clutter"]["coverage"]
    assert lam_r == pytest.approx(counted / FRAMES)
    assert "left out" in printed and "coverage" in printed
    assert float(clutter.magnitude) == pytest.approx(lam_r / meta["clutter"]["volume_mass"])
    assert lam_r == pytest.approx(SceneConfig().total_clutter_rate, rel=0.2)
    # the first frame's intensity: the gt boxes in view, every 10th of each trajectory
    *_, initial = load_context_parts(out)
    gt = np.loadtxt(scene_dir / "gt" / "gt.txt", delimiter=",", ndmin=2)
    in_span = gt[(gt[:, 0] <= FRAMES) & (gt[:, 6] != 0)]
    first = meta["initial"]
    assert first["source"] == "gt" and first["stride"] == 10
    assert first["magnitude"] == pytest.approx(len(in_span) / FRAMES)
    assert first["num_events"] >= len(in_span) / 10
    assert initial.dim == 6
    assert float(initial.magnitude) == pytest.approx(first["magnitude"] / first["volume_mass"])
    # where the targets are is learned: better than uniform on held-out frames
    assert first["heldout"]["heldout_gain"] > 1.0
    assert f"first frame: {first['num_events']} states from gt" in printed
    calibration = meta["score_calibration"]
    assert calibration["learned"] and calibration["source"] == "gt"
    assert f"score calibration from gt on {calibration['detections']} detections" in printed
    for name in ("intensities.png", "birth_evolution.png", "clutter_evolution.png"):
        data = (plots / name).read_bytes()
        assert data[:4] == b"\x89PNG" and len(data) > 10_000, name


def test_learns_clutter_from_labels(run_cli, scene, scene_dir, tmp_path):
    labelled = np.arange(10, FRAMES + 1, 10)
    det = scene.det_table
    chosen = scene.is_clutter & np.isin(det.frames, labelled)
    labels_path = tmp_path / "labels.json"
    save_clutter_labels(
        labels_path,
        ClutterLabels(
            sequence="SYN-2",
            image_size=(768, 576),
            labelled_frames=labelled,
            frames=det.frames[chosen],
            boxes=det.boxes[chosen],
        ),
    )
    out = tmp_path / "ctx.npz"
    code = run_cli(scene_dir, "--birth-from", "gt", "--clutter-from", labels_path, "--out", out)
    assert code == 0
    _, _, meta = load_context(out)
    assert meta["clutter"]["source"] == str(labels_path)
    assert meta["clutter"]["num_events"] == int(chosen.sum())
    assert meta["clutter"]["num_frames"] == labelled.size
    assert meta["clutter"]["magnitude"] == pytest.approx(chosen.sum() / labelled.size)


@pytest.mark.slow
def test_learns_from_a_tracker_run(run_cli, scene_dir, tmp_path):
    out = tmp_path / "ctx.npz"
    code = run_cli(
        scene_dir,
        "--frames",
        "1:150",
        "--clutter-from",
        "tracks",
        "--out",
        out,
        "--seed",
        1,
        "--first-frame",
    )
    assert code == 0
    _, _, meta = load_context(out)
    assert meta["birth"]["source"] == "tracks" and meta["clutter"]["source"] == "tracks"
    assert meta["birth"]["num_events"] > 0 and meta["seed"] == 1
    assert meta["initial"]["source"] == "tracks" and load_context_parts(out)[3] is not None
    # the tracker keeps true detections: its clutter rate is near the true one, not the
    # detection rate (about 10 targets per frame)
    assert meta["clutter"]["magnitude"] < 2 * SceneConfig().total_clutter_rate


def test_learns_with_the_evidence_confirmation(run_cli, scene_dir, tmp_path, capsys):
    """The documented flow: --config makes the UM run that yields the births use the evidence
    rule through the calibration learned first on the ground truth."""
    config = tmp_path / "evidence.json"
    config.write_text('{"confirmation": "evidence", "num_particles": 512}')
    out = tmp_path / "ctx.npz"
    assert run_cli(scene_dir, "--frames", "1:150", "--config", config, "--out", out) == 0
    _, _, meta = load_context(out)
    assert meta["birth"]["source"] == "tracks" and meta["birth"]["num_events"] > 0
    assert meta["score_calibration"]["learned"]
    printed = capsys.readouterr().out
    assert "score calibration from gt" in printed
    # no first-frame intensity unless asked for (--first-frame)
    assert "initial" not in meta and load_context_parts(out)[3] is None
    assert "first frame" not in printed


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (("--frames", f"1:{FRAMES + 1}"), "frame span"),
        (("--frames", "1:8", "--birth-from", "gt"), "no birth events"),
        (("--frames", "1:4", "--birth-from", "gt"), "warm-up"),
        (("--clutter-from", "missing.json"), "labels file"),
        (("--birth-epochs", "0"), "--birth-epochs"),
        (("--warmup", "-1"), "--warmup"),
        (("--video", "missing.avi"), "--video"),
        (("--config", "missing.json"), "missing.json"),
    ],
)
def test_bad_arguments_exit_2(run_cli, scene_dir, tmp_path, capsys, args, message):
    code = run_cli(scene_dir, "--out", tmp_path / "ctx.npz", *args)
    assert code == 2
    last_line = capsys.readouterr().err.strip().splitlines()[-1]
    assert last_line.startswith("jaxtrack learn-context: error:") and message in last_line
    assert not (tmp_path / "ctx.npz").exists()


def test_missing_ground_truth_and_bad_labels_exit_2(run_cli, scene_dir, tmp_path, capsys):
    no_gt = tmp_path / "no-gt"
    shutil.copytree(scene_dir, no_gt)
    shutil.rmtree(no_gt / "gt")
    assert run_cli(no_gt, "--birth-from", "gt", "--out", tmp_path / "a.npz") == 2
    assert "no ground truth" in capsys.readouterr().err
    bad = tmp_path / "labels.json"
    bad.write_text("{not json")
    # the labels are read before the (default) tracker run
    assert run_cli(scene_dir, "--clutter-from", bad, "--out", tmp_path / "b.npz") == 2
    error = capsys.readouterr().err
    assert str(bad) in error and "JSON" in error
    assert run_cli(tmp_path / "nowhere", "--out", tmp_path / "c.npz") == 2
    assert "not found" in capsys.readouterr().err
