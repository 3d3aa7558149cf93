"""``jaxtrack simulate``: files written, help, overrides and bad arguments (exit status 2)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.image import imread

from jaxtrack import cli
from jaxtrack.datasets import SceneConfig, config_from_dict, load_context_truth
from jaxtrack.datasets.scene_bank import family_config, generate_family_scene
from jaxtrack.io import load_sequence


@pytest.fixture
def run_cli(monkeypatch):
    """``jaxtrack.cli.main`` with only the simulate command registered.

    The dispatcher and its error handling are the real ones; registering only this command
    keeps the test independent of the other commands' modules.
    """
    monkeypatch.setattr(cli, "COMMANDS", ("simulate",))
    return lambda *argv: cli.main(["simulate", *map(str, argv)])


def test_simulate_writes_a_loadable_folder(run_cli, tmp_path, capsys):
    out = tmp_path / "SYN-01"
    assert run_cli("--seed", 4, "--out", out, "--num-frames", 60) == 0
    sequence = load_sequence(out)
    assert sequence.info.name == "SYN-01"
    assert sequence.info.seq_length == 60
    assert (sequence.info.im_width, sequence.info.im_height) == (768, 576)
    assert len(sequence.det_table) > 0 and len(sequence.gt_table) > 0
    birth, clutter = load_context_truth(out / "context_truth.npz")
    assert birth.dim == 6 and clutter.dim == 4
    assert float(clutter.magnitude) == pytest.approx(SceneConfig().total_clutter_rate)
    preview = imread(out / "preview.png")  # the 768 x 576 scene drawn, not a blank canvas
    assert preview.shape[0] >= 576 and preview.shape[1] >= 768
    assert np.unique(preview[..., :3].reshape(-1, 3), axis=0).shape[0] > 20
    printed = capsys.readouterr().out
    assert "wrote" in printed and "clutter" in printed and "detection rate" in printed


def test_same_seed_writes_identical_files(run_cli, tmp_path):
    for name in ("a", "b"):
        assert (
            run_cli("--seed", 9, "--out", tmp_path / name, "--num-frames", 30, "--name", "x") == 0
        )
    for name in ("det/det.txt", "gt/gt.txt", "seqinfo.ini"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_config_file_overrides_the_scene(run_cli, tmp_path):
    config = tmp_path / "quiet.json"
    config.write_text(json.dumps({"clutter_sources": [], "uniform_clutter_rate": 0}))
    out = tmp_path / "quiet"
    assert run_cli("--seed", 1, "--out", out, "--num-frames", 40, "--scene-config", config) == 0
    sequence = load_sequence(out)
    # Without clutter every detection is a target's: never more detections than targets.
    det_counts = np.bincount(sequence.det_table.frames, minlength=41)
    gt_counts = np.bincount(sequence.gt_table.frames, minlength=41)
    assert np.all(det_counts <= gt_counts)
    _, clutter = load_context_truth(out / "context_truth.npz")
    assert float(clutter.magnitude) == 0.0


def test_print_config_round_trips(run_cli, capsys):
    assert run_cli("--print-config", "--num-frames", 123) == 0
    config = config_from_dict(json.loads(capsys.readouterr().out))
    assert config == SceneConfig(num_frames=123)


def test_help_describes_the_outputs(run_cli, capsys):
    with pytest.raises(SystemExit) as exit_info:
        run_cli("--help")
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for word in ("--seed", "--out", "--num-frames", "--scene-config", "context_truth.npz"):
        assert word in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--seed", 0, "--out", "{tmp}/x", "--num-frames", 0], "--num-frames"),
        (["--seed", -1, "--out", "{tmp}/x"], "--seed"),
        (["--seed", 0], "--out"),
        (["--seed", 0, "--out", "{tmp}/x", "--preview-frame", 999, "--num-frames", 5], "preview"),
        (["--seed", 0, "--out", "{tmp}/x", "--scene-config", "{tmp}/missing.json"], "cannot read"),
        (["--seed", 0, "--out", "{tmp}/x", "--scene-config", "{tmp}/bad.json"], "not valid JSON"),
        (
            ["--seed", 0, "--out", "{tmp}/x", "--scene-config", "{tmp}/unknown.json"],
            "unknown field",
        ),
        (["--seed", 0, "--out", "{tmp}/file.txt"], "not a folder"),
        (["--seed", 0, "--out", "{tmp}/x", "--scene-config", "{tmp}/crowd.json"], "birth_rate"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(run_cli, tmp_path, capsys, args, message):
    (tmp_path / "bad.json").write_text("{not json")
    (tmp_path / "unknown.json").write_text('{"speed": 3}')
    (tmp_path / "file.txt").write_text("")
    (tmp_path / "crowd.json").write_text('{"birth_rate": 1000}')  # > MAX_TARGETS in view
    argv = [str(a).replace("{tmp}", str(tmp_path)) for a in args]
    assert run_cli(*argv) == 2
    error = capsys.readouterr().err
    assert error.startswith("jaxtrack simulate: error:") and message in error
    assert not (tmp_path / "x").exists()


def test_family_writes_the_bank_scene(run_cli, tmp_path, capsys):
    out = tmp_path / "street"
    assert run_cli("--family", "street", "--seed", 1, "--out", out) == 0
    sequence = load_sequence(out)
    scene = generate_family_scene("street", 1)
    assert sequence.info.name == "street-1" and sequence.info.seq_length == 600
    assert (sequence.info.im_width, sequence.info.im_height) == (720, 480)
    np.testing.assert_allclose(sequence.det_table.boxes, scene.det_table.boxes, atol=1e-9)
    assert "seed 1," in capsys.readouterr().out
    assert run_cli("--print-config", "--family", "flicker", "--seed", 2) == 0
    config = config_from_dict(json.loads(capsys.readouterr().out))
    assert config == family_config("flicker", 2)
