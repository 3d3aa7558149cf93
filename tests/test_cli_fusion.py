"""``jaxtrack track`` / ``track-video`` with ``--tracker fusion``: ``--pool`` (normalised, bad
members refused), ``--fusion``, ``--train-frames`` (recorded in ``.config.json``, refused
outside the tracked frames, with ``--benchmark`` and for other trackers), and
``--annotate`` drawing the pool's members, the fused boxes and the hypotheses on a synthetic
walker."""

from __future__ import annotations

import argparse
import json

import cv2
import numpy as np
import pytest

from jaxtrack.association.smoothing import smooth_tracks
from jaxtrack.cli import main
from jaxtrack.commands.arguments import apply_fusion_arguments, parse_pool
from jaxtrack.errors import InputError
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.io import read_mot_file, write_seqinfo
from jaxtrack.io.video import id_colour
from jaxtrack.pipelines.tracking import smoothing_noise
from jaxtrack.plot.fusion_frames import (
    HYPOTHESIS_COLOUR,
    LEGEND_MARGIN,
    LEGEND_ROW,
    LEGEND_WIDTH,
    MEMBER_COLOURS,
)
from jaxtrack.types import SequenceInfo
from tests.cli_workspace import run_refused
from tests.synthetic_video import NUM_FRAMES, SIZE, person_box, write_synthetic_folder

#: Frames tracked by the runs (short: the compile dominates); both runs use one pool and rule,
#: so the second reuses the first's compiled step.
FRAMES = 16
POOL = ["--pool", "classifier,detection", "--fusion", "naive"]


def walker_rows(kind: str) -> str:
    """The walker's true box on every frame, as ``det.txt`` or ``gt.txt`` rows."""
    tail = "1,-1,-1,-1" if kind == "det" else "1,1,1"
    rows = [
        f"{k},{-1 if kind == 'det' else 1},{','.join(map(str, person_box(k)))},{tail}"
        for k in range(1, NUM_FRAMES + 1)
    ]
    return "\n".join(rows) + "\n"


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    """A sequence folder: the walker's frames (img1/), its boxes as det.txt and gt.txt."""
    folder = tmp_path_factory.mktemp("fusion") / "Walk"
    folder.mkdir()
    write_synthetic_folder(folder / "img1")
    write_seqinfo(folder / "seqinfo.ini", SequenceInfo("Walk", NUM_FRAMES, *SIZE, 7.0))
    for kind in ("det", "gt"):
        (folder / kind).mkdir()
        (folder / kind / f"{kind}.txt").write_text(walker_rows(kind))
    return folder


@pytest.mark.parametrize(
    ("text", "pool"),
    [
        ("predictor,detection", "detection,predictor"),
        ("classifier", "classifier"),
        (" predictor , classifier,detection", "detection,classifier,predictor"),
    ],
)
def test_pool_in_any_order_is_normalised(text, pool):
    assert parse_pool(text) == pool


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("detection,radar", "unknown member 'radar'; the members are detection, classifier"),
        ("detection,detection", "a member named twice"),
        ("", "name at least one member of detection, classifier, predictor"),
        (" , ", "name at least one member"),
    ],
)
def test_bad_pool_is_refused(text, message):
    with pytest.raises(argparse.ArgumentTypeError, match=message):
        parse_pool(text)


REFUSED = [
    ("track {seq} --out {tmp}/r.txt --pool detection", "--pool applies to --tracker fusion"),
    (
        "track {seq} --out {tmp}/r.txt --tracker cmt --fusion naive",
        "--fusion applies to --tracker fusion, not to cmt",
    ),
    (
        "track {seq} --out {tmp}/r.txt --tracker hierarchical --train-frames 1:2",
        "--train-frames applies to --tracker fusion, not to hierarchical",
    ),
    (
        "track --benchmark {mot} --out {tmp}/res --tracker fusion --train-frames 1:2",
        "--train-frames applies to one sequence, not to --benchmark",
    ),
    (
        "track {seq} --out {tmp}/r.txt --tracker fusion --pool detection,radar",
        "argument --pool: unknown member 'radar'; the members are detection, classifier, predictor",
    ),
    (
        "track {seq} --out {tmp}/r.txt --tracker fusion --frames 1:3 --train-frames 2:5",
        "--train-frames 2:5 must lie inside the tracked frames 1:3",
    ),
    (
        "track {seq} --out {tmp}/r.txt --tracker fusion --train-frames 5",
        "--train-frames 5: frame span must look like A:B",
    ),
    ("track-video {frames} --out {tmp}/r.txt --pool detection", "--pool applies to"),
    (
        "track-video {frames} --out {tmp}/r.txt --tracker kalman --train-frames 1:2",
        "--train-frames applies to --tracker fusion, not to kalman",
    ),
    (
        "track-video {frames} --out {tmp}/r.txt --tracker fusion --frames 1:2 --train-frames 1:3",
        "--train-frames 1:3 must lie inside the tracked frames 1:2",
    ),
]


@pytest.mark.parametrize(("arguments", "message"), REFUSED)
def test_refused_fusion_options_exit_2(workspace, tmp_path, capsys, arguments, message):
    line = run_refused(capsys, tmp_path, arguments.format(**workspace).split())
    assert message in line


def test_track_records_pool_fusion_and_training(sequence, tmp_path, capsys):
    out = tmp_path / "res.txt"
    argv = ["track", str(sequence), "--tracker", "fusion", "--frames", f"1:{FRAMES}", *POOL]
    assert main([*argv, "--train-frames", "3:12", "--out", str(out), "--quiet"]) == 0
    result = read_mot_file(out, "res", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1 and len(result) >= FRAMES - 2
    truth = np.array([person_box(k) for k in result.frames], float)
    assert np.abs(result.boxes - truth).max() < 3.0
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["tracker"] == "fusion" and used["frames"] == [1, FRAMES]
    assert used["pool"] == "detection,classifier" and used["fusion"] == "naive"
    assert used["training"].startswith("trained on frames 3:12; ground-truth trajectories")
    assert used["training"] in capsys.readouterr().err


def test_the_offline_output_is_smoothed_by_default(sequence, tmp_path, capsys):
    """The default offline output is the ``{"smoothing": "none"}`` output re-estimated by
    the Rauch-Tung-Striebel smoother under the PHD tracker's default noise (session 63):
    the same rows, frames and identities, other boxes. The online output has nothing to
    smooth: its default is ``"none"``, and asking for ``"rts"`` there is refused."""
    argv = ["track", str(sequence), "--tracker", "fusion", "--frames", f"1:{FRAMES}", *POOL]
    plain_config = tmp_path / "plain.json"
    plain_config.write_text(json.dumps({"smoothing": "none"}))
    smoothed, plain = tmp_path / "smoothed.txt", tmp_path / "plain.txt"
    assert main([*argv, "--out", str(smoothed), "--quiet"]) == 0
    assert main([*argv, "--config", str(plain_config), "--out", str(plain), "--quiet"]) == 0
    capsys.readouterr()
    smoothed_rows = read_mot_file(smoothed, "res", NUM_FRAMES)
    plain_rows = read_mot_file(plain, "res", NUM_FRAMES)
    expected = smooth_tracks(plain_rows, *smoothing_noise(FusionConfig()))
    np.testing.assert_array_equal(smoothed_rows.frames, expected.frames)
    np.testing.assert_array_equal(smoothed_rows.ids, expected.ids)
    np.testing.assert_allclose(smoothed_rows.boxes, expected.boxes, atol=0.01)
    assert np.abs(smoothed_rows.boxes - plain_rows.boxes).max() > 0.01
    used = json.loads((tmp_path / "smoothed.config.json").read_text())
    assert used["smoothing"] == "rts"
    assert FusionConfig().smoothing == "rts"
    assert FusionConfig(output="online").smoothing == "none"
    assert FusionConfig.from_dict({"output": "online"}).smoothing == "none"
    with pytest.raises(InputError, match="smoothing 'rts'"):
        FusionConfig(output="online", smoothing="rts")
    # a change of output alone follows the output's default; a smoothing given is kept
    assert FusionConfig().replace(output="online").smoothing == "none"
    assert FusionConfig(output="online").replace(output="offline").smoothing == "rts"
    assert FusionConfig(smoothing="none").replace(output="online").smoothing == "none"
    assert FusionConfig(smoothing="none").replace(output="offline").smoothing == "none"
    assert FusionConfig().replace(max_gap=3).smoothing == "rts"
    with pytest.raises(InputError, match="smoothing 'rts'"):
        FusionConfig().replace(output="online", smoothing="rts")


def test_track_video_annotates_members_fused_box_and_hypothesis(sequence, tmp_path, capsys):
    det = tmp_path / "det.txt"
    det.write_text(walker_rows("det"))
    out = tmp_path / "res.txt"
    frames_dir = tmp_path / "annotated"
    argv = ["track-video", str(sequence / "img1"), "--frames", f"1:{FRAMES}", "--fps", "7"]
    argv += ["--detections", str(det), "--tracker", "fusion", *POOL, "--quiet"]
    assert main([*argv, "--out", str(out), "--annotate", str(frames_dir)]) == 0
    result = read_mot_file(out, "res", NUM_FRAMES)
    (identity,) = set(result.ids.tolist())
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["pool"] == "detection,classifier" and used["fusion"] == "naive"
    # no ground truth beside a video: the PHD tracker's tracks, the paper's thresholds
    assert used["training"].startswith(f"trained on frames 1:{FRAMES // 2}; PHD tracks")
    assert "the paper's thresholds (th_init 3, th_term 8)" in used["training"]
    assert used["training"] in capsys.readouterr().err

    def frame(k):
        return cv2.cvtColor(cv2.imread(str(frames_dir / f"{k:06d}.png")), cv2.COLOR_BGR2RGB)

    def left_edge(k):
        x, y, _, h = result.boxes[result.frames == k][0]
        return round(x), round(y + h / 2)

    # frame 1: a hypothesis (th_init 3): its box grey, two pixels wide over the result's box
    x, y = left_edge(1)
    assert tuple(frame(1)[y, x]) == HYPOTHESIS_COLOUR
    # frame 10: a target, its fused box thick (4 pixels) in its identity's colour
    x, y = left_edge(10)
    image = frame(10)
    assert all(tuple(image[y, x + dx]) == id_colour(identity) for dx in range(-2, 2))
    # the key lists the members that responded: detection and classifier, not the predictor
    left = SIZE[0] - LEGEND_MARGIN - LEGEND_WIDTH
    for row, colour in enumerate(MEMBER_COLOURS[:2]):
        assert tuple(image[LEGEND_MARGIN + LEGEND_ROW * row + LEGEND_ROW // 2 + 2, left + 8]) == (
            colour
        )
    legend = image[: LEGEND_MARGIN + LEGEND_ROW * 5 + 5, left:]  # 2 members, 3 styles
    assert not np.all(legend == MEMBER_COLOURS[2], axis=-1).any()


def test_help_explains_the_fusion_options(capsys):
    texts = {}
    for command in ("track", "track-video"):
        with pytest.raises(SystemExit) as exit_info:
            main([command, "--help"])
        assert exit_info.value.code == 0
        texts[command] = " ".join(capsys.readouterr().out.replace("``", "").split())
        assert "--tracker fusion runs" in texts[command]
        assert "--pool MEMBERS" in texts[command] and "--fusion {proposed,naive}" in texts[command]
        assert "--train-frames A:B --tracker fusion's training span" in texts[command]
    assert "refused with --benchmark, where each sequence trains on" in texts["track"]
    assert "its voting thresholds are the paper's" in texts["track-video"]
    assert "each pool member's response box thin" in texts["track-video"]


def test_pool_and_fusion_override_the_configuration_file():
    from_file = FusionConfig(pool="detection", fusion="naive", max_targets=8)
    given = argparse.Namespace(
        tracker="fusion", pool="classifier,predictor", fusion=None, train_frames=None
    )
    config = apply_fusion_arguments(given, from_file)
    assert (config.pool, config.fusion, config.max_targets) == ("classifier,predictor", "naive", 8)
    none = argparse.Namespace(tracker="fusion", pool=None, fusion=None, train_frames="1:5")
    assert apply_fusion_arguments(none, from_file) == from_file
