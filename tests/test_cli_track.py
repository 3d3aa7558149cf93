"""``jaxtrack track``: results written in MOT format, config handling, bad input exit 2."""

from __future__ import annotations

import json

import jax.numpy as jnp
import numpy as np
import pytest
from matplotlib.image import imread

from jaxtrack.cli import main
from jaxtrack.commands.arguments import load_config
from jaxtrack.context.io import save_context
from jaxtrack.context.scores import knot_scores
from jaxtrack.errors import FileFormatError
from jaxtrack.filters.phd_tracker import PHDConfig, phd_params
from jaxtrack.io import read_mot_file, read_seqinfo
from jaxtrack.metrics.evaluate import evaluate_sequence


def test_track_writes_results_and_config(mot15_root, tmp_path, capsys):
    out = tmp_path / "campus.txt"
    config = tmp_path / "small.json"
    config.write_text(json.dumps({"num_particles": 512, "births_per_detection": 8}))
    code = main(
        ["track", str(mot15_root / "TUD-Campus"), "--out", str(out), "--config", str(config)]
    )
    assert code == 0 and "wrote" in capsys.readouterr().out
    result = read_mot_file(out, "res", seq_length=71)
    assert len(result) > 0 and result.ids.min() >= 1
    used = json.loads((tmp_path / "campus.config.json").read_text())
    assert used["num_particles"] == 512 and used["clutter_rate"] == PHDConfig().clutter_rate
    gt = read_mot_file(mot15_root / "TUD-Campus" / "gt" / "gt.txt", "gt")
    scores = evaluate_sequence(gt, result, frames=(1, 71)).summary()
    assert scores["MOTA"] > 0.3  # a working tracker on an easy sequence, not a perfect one


def test_track_frame_span(mot15_root, tmp_path):
    out = tmp_path / "span.txt"
    assert (
        main(["track", str(mot15_root / "TUD-Campus"), "--out", str(out), "--frames", "20:40"]) == 0
    )
    frames = read_mot_file(out, "res").frames
    assert frames.min() >= 20 and frames.max() <= 40


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("{", "not valid JSON"),
        ("[1]", "JSON object"),
        ('{"particles": 3}', r"unknown phd configuration key\(s\) 'particles'"),
        ('{"num_particles": "many"}', "num_particles must be an integer"),
        ('{"clutter_rate": -1}', r"clutter_rate must lie in \(0, 10000\]"),
        ('{"extraction": "kmeans"}', "extraction must be"),
        ('{"output": "batch"}', "output must be"),
        ('{"max_gap": -1}', r"max_gap must lie in \[0, 1000\]"),
        ('{"max_gap": 2.5}', "max_gap must be an integer"),
    ],
)
def test_bad_config(tmp_path, text, message):
    path = tmp_path / "c.json"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=message):
        load_config(str(path))


def test_bad_arguments_exit_2(mot15_root, tmp_path, capsys):
    assert main(["track", "--out", str(tmp_path / "x.txt")]) == 2
    assert "either SEQ_DIR or --benchmark" in capsys.readouterr().err
    assert main(["track", str(tmp_path / "nope"), "--out", str(tmp_path / "x.txt")]) == 2
    assert "sequence folder not found" in capsys.readouterr().err


def test_track_with_context_variant_and_figure(mot15_root, tmp_path, capsys):
    info = read_seqinfo(mot15_root / "TUD-Campus" / "seqinfo.ini")
    uniform = phd_params(PHDConfig(), info)
    birth = uniform.birth_intensity._replace(
        weights=jnp.ones(1),
        means=jnp.array([[300.0, 0.0, 300.0, 0.0, 60.0, 150.0]]),
        covs=jnp.diag(jnp.array([50.0, 3.0, 50.0, 3.0, 20.0, 40.0]) ** 2)[None],
        uniform_weight=jnp.asarray(0.5),
    )
    context = tmp_path / "ctx.npz"
    save_context(
        context,
        birth,
        uniform.clutter_intensity,
        {"birth": {"magnitude": 0.05}, "clutter": {"magnitude": 0.4}},
    )
    out = tmp_path / "a3.txt"
    figure = tmp_path / "fig.png"
    args = ["track", str(mot15_root / "TUD-Campus"), "--out", str(out), "--context", str(context)]
    assert main([*args, "--variant", "A3", "--figure", str(figure), "--figure-frame", "30"]) == 0
    assert "frame 30" in capsys.readouterr().out
    pixels = imread(figure)  # the image drawn at its size, more than a blank canvas
    assert pixels.shape[0] >= info.im_height and pixels.shape[1] >= info.im_width
    assert np.unique(pixels[..., :3].reshape(-1, 3), axis=0).shape[0] > 20
    used = json.loads((tmp_path / "a3.config.json").read_text())
    assert used["variant"] == "A3" and used["context"] == str(context)
    assert len(read_mot_file(out, "res")) > 0
    assert main([*args, "--figure", str(figure), "--figure-frame", "99"]) == 2
    assert "outside the frames tracked" in capsys.readouterr().err


def test_track_with_a_context_variant_um_reads_its_score_calibration(mot15_root, tmp_path):
    """--variant UM with a context: uniform intensities, the context's calibration. A
    calibration that makes every detection near-certain (0.99) confirms every track on its
    first detection under the evidence rule, as does the score rule only for detections of
    0.97 or more, so the evidence run outputs at least the score run's boxes."""
    info = read_seqinfo(mot15_root / "TUD-Campus" / "seqinfo.ini")
    uniform = phd_params(PHDConfig(), info)
    knots = knot_scores()
    record = {"scores": knots.tolist(), "probabilities": [0.99] * len(knots)}
    context = tmp_path / "ctx.npz"
    save_context(
        context,
        uniform.birth_intensity,
        uniform.clutter_intensity,
        {"score_calibration": {"learned": True, "source": "gt", **record}},
    )
    config = tmp_path / "evidence.json"
    config.write_text('{"confirmation": "evidence", "num_particles": 256}')
    runs = {}
    for name, extra in (("um", ["--variant", "UM"]), ("plain", [])):
        out = tmp_path / f"{name}.txt"
        args = ["track", str(mot15_root / "TUD-Campus"), "--out", str(out), "--frames", "1:30"]
        args += ["--config", str(config), *(["--context", str(context)] if extra else [])]
        assert main([*args, *extra]) == 0
        runs[name] = read_mot_file(out, "res")
    used = json.loads((tmp_path / "um.config.json").read_text())
    assert used["variant"] == "UM" and used["confirmation"] == "evidence"
    # Without the context the scores are read as probabilities (median 0.99 on TUD-Campus,
    # some below 0.7): the 0.99 calibration confirms every track at once, so more boxes.
    assert len(runs["um"]) > len(runs["plain"]) > 0


def test_context_from_another_image_size_is_refused(mot15_root, tmp_path, capsys):
    params = phd_params(PHDConfig(), read_seqinfo(mot15_root / "PETS09-S2L1" / "seqinfo.ini"))
    context = tmp_path / "pets.npz"
    save_context(context, params.birth_intensity, params.clutter_intensity)
    args = ["track", str(mot15_root / "TUD-Campus"), "--out", str(tmp_path / "x.txt")]
    assert main([*args, "--context", str(context)]) == 2
    assert "learned on 768x576 images" in capsys.readouterr().err


def test_track_kalman_presets_write_results_and_config(mot15_root, tmp_path, capsys):
    gt = read_mot_file(mot15_root / "TUD-Campus" / "gt" / "gt.txt", "gt")
    for preset, cost, gate in (("default", "likelihood", 9.4877), ("sort", "iou", "inf")):
        out = tmp_path / f"{preset}.txt"
        args = ["track", str(mot15_root / "TUD-Campus"), "--out", str(out), "--tracker", "kalman"]
        assert main([*args, "--preset", preset]) == 0 and "wrote" in capsys.readouterr().out
        used = json.loads((tmp_path / f"{preset}.config.json").read_text())
        assert used["tracker"] == "kalman" and used["preset"] == preset and used["cost"] == cost
        assert used["params"]["gate"] == gate and used["output"] == "offline"
        assert "num_particles" not in used and used["frames"] == [1, 71]
        result = read_mot_file(out, "res", seq_length=71)
        assert evaluate_sequence(gt, result, frames=(1, 71)).summary()["MOTA"] > 0.3


def test_track_kalman_benchmark_and_online_output(mot15_root, tmp_path):
    root = tmp_path / "bench"
    root.mkdir()
    for name in ("TUD-Campus", "KITTI-17"):
        (root / name).symlink_to(mot15_root / name)
    config = tmp_path / "online.json"
    config.write_text(json.dumps({"output": "online"}))
    out = tmp_path / "res"
    args = ["track", "--benchmark", str(root), "--out", str(out), "--tracker", "kalman"]
    assert main([*args, "--config", str(config)]) == 0
    for name in ("TUD-Campus", "KITTI-17"):
        used = json.loads((out / f"{name}.config.json").read_text())
        assert used["tracker"] == "kalman" and used["output"] == "online"
        assert len(read_mot_file(out / f"{name}.txt", "res")) > 0


def test_track_kalman_refuses_phd_options(mot15_root, tmp_path, capsys):
    args = ["track", str(mot15_root / "TUD-Campus"), "--out", str(tmp_path / "x.txt")]
    assert main([*args, "--preset", "sort"]) == 2
    assert "--preset applies to --tracker kalman" in capsys.readouterr().err
    kalman = [*args, "--tracker", "kalman"]
    assert main([*kalman, "--context", str(tmp_path / "ctx.npz")]) == 2
    assert "--context applies to the PHD tracker" in capsys.readouterr().err
    config = tmp_path / "phd.json"
    config.write_text(json.dumps({"num_particles": 512}))
    assert main([*kalman, "--config", str(config)]) == 2
    assert "unknown kalman configuration key(s) 'num_particles'" in capsys.readouterr().err
    assert main([*kalman, "--preset", "fast"]) == 2
    assert "invalid choice: 'fast'" in capsys.readouterr().err
