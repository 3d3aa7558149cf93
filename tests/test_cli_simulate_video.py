"""``jaxtrack simulate --video``: the folder, inspect on it, the config round trip, refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack import cli
from jaxtrack.datasets import VideoSceneConfig, generate_video_scene, video_config_from_dict
from jaxtrack.io import load_sequence

#: A small, quick scene: 160x120 (the default layout scaled by 1/4), 400 frames.
SMALL = {"image_width": 160, "image_height": 120, "num_frames": 400}


@pytest.fixture
def run_cli(monkeypatch):
    """``jaxtrack.cli.main`` with only simulate and inspect registered."""
    monkeypatch.setattr(cli, "COMMANDS", ("simulate", "inspect"))
    return lambda *argv: cli.main([*map(str, argv)])


@pytest.fixture
def small_config(tmp_path):
    path = tmp_path / "small.json"
    path.write_text(json.dumps(SMALL))
    return path


def test_video_folder_and_inspect(run_cli, tmp_path, small_config, capsys):
    out = tmp_path / "v3"
    assert (
        run_cli("simulate", "--video", "--seed", 3, "--out", out, "--scene-config", small_config)
        == 0
    )
    printed = capsys.readouterr().out
    assert "v3.mp4: rendered and encoded at" in printed
    for kind in ("crossing", "group", "occlusion", "standing"):
        assert f"  {kind}: id " in printed
    scene = generate_video_scene(3, VideoSceneConfig(name="v3", **SMALL))
    sequence = load_sequence(out)
    assert sequence.info == scene.info
    np.testing.assert_array_equal(sequence.gt_table.boxes, scene.gt_table.boxes)
    truth = json.loads((out / "video_truth.json").read_text())
    assert truth["video"] == "v3.mp4" and truth["config"]["name"] == "v3"
    assert run_cli("inspect", out, "--json") == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 400 and summary["gt_ids"] == scene.num_people
    assert summary["frames_source"] == {
        "path": str(out / "v3.mp4"),
        "frames": 400,
        "width": 160,
        "height": 120,
        "fps": 25.0,
    }
    assert run_cli("inspect", out) == 0
    assert f"frames from   {out / 'v3.mp4'}  (400 frames, 160 x 120 at 25.0 fps)" in (
        capsys.readouterr().out
    )


def test_same_seed_same_files_and_rewrite_allowed(run_cli, tmp_path, small_config):
    for name in ("a", "b", "b"):  # "b" twice: a folder simulate --video wrote may be rewritten
        argv = ("--seed", 5, "--out", tmp_path / name, "--name", "x", "--quiet")
        assert run_cli("simulate", "--video", *argv, "--scene-config", small_config) == 0
    for name in ("det/det.txt", "gt/gt.txt", "seqinfo.ini", "video_truth.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()


def test_print_config_round_trips(run_cli, capsys):
    assert run_cli("simulate", "--video", "--print-config", "--num-frames", 450) == 0
    config = video_config_from_dict(json.loads(capsys.readouterr().out))
    assert config == VideoSceneConfig(num_frames=450)


def test_help_explains_the_video(run_cli, capsys):
    with pytest.raises(SystemExit) as exit_info:
        run_cli("simulate", "--help")
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for word in ("--video", "--quiet", "video_truth.json", "NAME.mp4", "visibility"):
        assert word in text


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--video", "--out", "{tmp}/x", "--family", "street"], "--family does not apply"),
        (["--video", "--out", "{tmp}/x", "--preview-frame", 3], "--preview-frame does not"),
        (["--out", "{tmp}/x", "--quiet"], "--quiet needs --video"),
        (["--video", "--print-config", "--seed", 2], "--seed does nothing"),
        (["--video", "--print-config", "--out", "{tmp}/x"], "--out does nothing"),
        (["--video"], "--out DIR is required"),
        (["--video", "--out", "{tmp}/x", "--name", "a/b"], "cannot name the video file"),
        (["--video", "--out", "{tmp}/x", "--num-frames", 100], "at least"),
        (["--video", "--out", "{tmp}/x", "--scene-config", "{tmp}/scene.json"], "unknown field"),
        (["--video", "--out", "{tmp}/mot"], "did not write"),
    ],
)
def test_bad_arguments_exit_2(run_cli, tmp_path, capsys, args, message):
    # A detection-level scene's config is not a video scene's; a MOT folder is not ours.
    (tmp_path / "scene.json").write_text('{"birth_rate": 0.1}')
    (tmp_path / "mot").mkdir()
    (tmp_path / "mot" / "seqinfo.ini").write_text("[Sequence]\n")
    argv = [str(a).replace("{tmp}", str(tmp_path)) for a in args]
    assert run_cli("simulate", *argv) == 2
    error = capsys.readouterr().err
    assert error.startswith("jaxtrack simulate: error:") and message in error
    assert not (tmp_path / "x").exists()
    assert (tmp_path / "mot" / "seqinfo.ini").read_text() == "[Sequence]\n"


def test_inspect_says_when_a_folder_has_no_frames(run_cli, mot15_root, capsys):
    assert run_cli("inspect", mot15_root / "PETS09-S2L1", "--json") == 0
    assert json.loads(capsys.readouterr().out)["frames_source"] is None
    assert run_cli("inspect", mot15_root / "PETS09-S2L1") == 0
    assert "frames from   none (no img1/ or NAME.mp4/.avi in the folder)" in capsys.readouterr().out
