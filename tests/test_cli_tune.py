"""``jaxtrack tune``: writes a configuration that ``jaxtrack track --config`` uses, or with
``--context`` a tuned context that ``jaxtrack track --context`` uses; bad input exits 2 with a
message."""

from __future__ import annotations

import dataclasses
import json

import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.commands.arguments import load_config
from jaxtrack.context.io import load_context, save_context
from jaxtrack.datasets import SceneConfig, generate_scene
from jaxtrack.datasets.synthetic import write_scene
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.io import read_mot_file

SMALL = ["--steps", "3", "--keys", "1", "--particles", "64", "--births-per-detection", "4"]


def test_tune_writes_a_config_that_track_uses(mot15_root, tmp_path, capsys):
    base = tmp_path / "base.json"
    base.write_text(json.dumps({"num_particles": 128, "births_per_detection": 4}))
    out = tmp_path / "tuned.json"
    sequence = str(mot15_root / "TUD-Campus")
    code = main(
        ["tune", sequence, "--frames", "1:30", "--config", str(base), "--out", str(out), *SMALL]
    )
    assert code == 0
    printed = capsys.readouterr().out
    assert "wrote" in printed and "clutter_rate 1 ->" in printed
    config = json.loads(out.read_text())
    # The base overrides are kept, the tuned magnitudes added: a valid --config file.
    assert config["num_particles"] == 128 and config["births_per_detection"] == 4
    assert config["clutter_rate"] > 0 and config["birth_rate"] > 0
    assert config["clutter_rate"] != 1.0  # three adam steps of 0.1 moved it
    assert load_config(str(out)).clutter_rate == config["clutter_rate"]
    report = json.loads((tmp_path / "tuned.tuning.json").read_text())
    assert report["objective"] == "likelihood" and report["frames"] == [1, 30]
    assert len(report["history"]["loss"]) == 3 and report["filter_runs"] == 3
    assert report["start"]["clutter_rate"] == 1.0
    assert report["tuned"]["clutter_rate"] == pytest.approx(config["clutter_rate"], rel=1e-5)
    result = tmp_path / "t.txt"
    args = ["track", sequence, "--frames", "31:60", "--config", str(out), "--out", str(result)]
    assert main(args) == 0
    assert len(read_mot_file(result, "res", seq_length=71)) > 0
    used = json.loads((tmp_path / "t.config.json").read_text())
    assert used["clutter_rate"] == config["clutter_rate"]


def test_tune_supervised_and_extra_parameters_note(mot15_root, tmp_path, capsys):
    out = tmp_path / "sup.json"
    args = ["tune", str(mot15_root / "TUD-Campus"), "--frames", "1:20", "--out", str(out)]
    code = main(
        [*args, "--objective", "supervised", "--tune", "clutter_rate,detection_prob", *SMALL]
    )
    assert code == 0
    report = json.loads((tmp_path / "sup.tuning.json").read_text())
    assert report["objective"] == "supervised" and "detection_prob" in report["tuned"]
    # The tuned detection probability travels in the config that `jaxtrack track` reads.
    config = json.loads(out.read_text())
    assert config["detection_prob"] == pytest.approx(report["tuned"]["detection_prob"], rel=1e-5)
    assert PHDConfig.from_dict(config).detection_prob == config["detection_prob"]


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--tune", "clutter,birth_rate"], "unknown tunable parameter(s) clutter"),
        (["--steps", "0"], "argument --steps: value must lie in [1, 1000000], got 0"),
        (["--frames", "50:10"], "frame"),
    ],
)
def test_bad_input_exits_2_with_a_message(mot15_root, tmp_path, capsys, extra, message):
    out = tmp_path / "x.json"
    code = main(["tune", str(mot15_root / "TUD-Campus"), "--out", str(out), *extra])
    assert code == 2
    error = capsys.readouterr().err
    assert error.startswith("jaxtrack tune: error:") and message in error
    assert not out.exists()


def test_out_must_be_json(mot15_root, tmp_path, capsys):
    code = main(["tune", str(mot15_root / "TUD-Campus"), "--out", str(tmp_path / "x.txt")])
    assert code == 2 and "--out must be a .json file" in capsys.readouterr().err


@pytest.fixture(scope="module")
def context_scene(tmp_path_factory):
    """A small synthetic scene and a context like learn-context's: its true densities with a
    uniform share of 0.3 for births, the events per frame and volume masses recorded."""
    root = tmp_path_factory.mktemp("tune-context")
    scene = generate_scene(4, dataclasses.replace(SceneConfig(), num_frames=40))
    sequence = write_scene(scene, root / "SYN-4")
    birth = scene.birth_intensity._replace(uniform_weight=jnp.asarray(0.3, jnp.float32))
    metadata = {
        "birth": {"magnitude": float(birth.magnitude), "volume_mass": 1.0},
        "clutter": {"magnitude": float(scene.clutter_intensity.magnitude), "volume_mass": 1.0},
    }
    context = root / "ctx.npz"
    save_context(context, birth, scene.clutter_intensity, metadata)
    return sequence, context


def test_tune_context_writes_a_context_that_track_uses(context_scene, tmp_path, capsys):
    sequence, context = context_scene
    base = tmp_path / "base.json"
    base.write_text(json.dumps({"num_particles": 128, "births_per_detection": 4}))
    out = tmp_path / "tuned.npz"
    args = ["tune", str(sequence), "--frames", "1:20", "--context", str(context), "--out", str(out)]
    assert main([*args, "--config", str(base), "--json", *SMALL]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["config_file"] == str(tmp_path / "tuned.config.json")
    assert report["variant"] == "GM" and report["frames"] == [1, 20]
    names = {"birth_rate", "clutter_rate", "birth_uniform_share", "clutter_uniform_share"}
    assert set(report["tuned"]) == names
    assert report["start"]["birth_uniform_share"] == pytest.approx(0.3)
    for name in names:  # three adam steps of 0.1 (log / logit units) moved every value
        assert report["tuned"][name] != pytest.approx(report["start"][name], rel=1e-3)
    # The saved context holds the tuned values, and its metadata records the tuning.
    birth, clutter, metadata = load_context(out)
    assert float(birth.magnitude) == pytest.approx(report["tuned"]["birth_rate"], rel=1e-5)
    assert float(clutter.magnitude) == pytest.approx(report["tuned"]["clutter_rate"], rel=1e-5)
    assert float(birth.uniform_weight) == pytest.approx(
        report["tuned"]["birth_uniform_share"], rel=1e-5
    )
    assert float(clutter.uniform_weight) == pytest.approx(
        report["tuned"]["clutter_uniform_share"], rel=1e-5
    )
    original = load_context(context)
    np.testing.assert_array_equal(birth.means, original[0].means)
    (record,) = metadata["tuning"]
    assert record["frames"] == [1, 20] and record["objective"] == "likelihood"
    assert record["start"] == report["start"] and record["tuned"] == report["tuned"]
    assert metadata["birth"]["uniform_weight"] == pytest.approx(float(birth.uniform_weight))
    # No configuration key was tuned: the configuration is the --config one.
    assert json.loads((tmp_path / "tuned.config.json").read_text()) == json.loads(base.read_text())
    # jaxtrack track reads the tuned context.
    result = tmp_path / "t.txt"
    track = ["track", str(sequence), "--frames", "21:40", "--context", str(out)]
    assert main([*track, "--config", str(base), "--out", str(result), "--quiet"]) == 0
    assert len(read_mot_file(result, "res")) > 0
    assert json.loads((tmp_path / "t.config.json").read_text())["context"] == str(out)


def test_tune_context_refusals(context_scene, tmp_path, capsys):
    sequence, context = context_scene
    args = ["tune", str(sequence), "--context", str(context)]
    assert main([*args, "--out", str(tmp_path / "x.json")]) == 2
    assert "--out must be a .npz file with --context" in capsys.readouterr().err
    a2 = ["--variant", "A2", "--tune", "birth_uniform_share", "--out", str(tmp_path / "x.npz")]
    assert main([*args, *a2]) == 2
    assert "variant A2 uses no learned birth density" in capsys.readouterr().err
    plain = ["tune", str(sequence), "--tune", "clutter_uniform_share"]
    assert main([*plain, "--out", str(tmp_path / "x.json")]) == 2
    assert "needs a learned context (--context CTX.npz)" in capsys.readouterr().err
    assert main([*plain, "--variant", "A1", "--out", str(tmp_path / "x.json")]) == 2
    assert "--variant needs --context" in capsys.readouterr().err
