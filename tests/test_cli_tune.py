"""``jaxtrack tune``: writes a configuration that ``jaxtrack track --config`` uses; bad input
exits 2 with a message."""

from __future__ import annotations

import json

import pytest

from jaxtrack.cli import main
from jaxtrack.commands.arguments import load_config
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
