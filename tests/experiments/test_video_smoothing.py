"""``--smoothing`` of the experiments on the MOT15 videos and the scripted scenes
(cmt-ablation, hierarchical, fusion): it reaches every compared tracker's configuration (and
only the trackers), the record and ``table.md`` say so; ``--tracker-seeds``, which only the
CMT ablation reads, is refused by the other two instead of being ignored."""

from __future__ import annotations

import json

import pytest

from jaxtrack.cli import main
from jaxtrack.commands import cmt_ablation as cmt_command
from jaxtrack.commands import fusion_experiment, hierarchical_experiment
from jaxtrack.errors import InputError
from jaxtrack.experiments import cmt_ablation, fusion, hierarchical
from jaxtrack.experiments.common import (
    environment,
    environment_line,
    smoothed_names,
    smoothed_trackers,
    smoothing_sentence,
)
from jaxtrack.filters.fusion_tracker import FusionConfig


class Captured(Exception):
    """Raised by the stand-in run loop once it has seen the trackers."""


def test_smoothed_trackers_sets_every_configuration_and_keeps_the_order():
    trackers = fusion.experiment_trackers()
    smoothed = smoothed_trackers(trackers, "rts")
    assert list(smoothed) == list(trackers)
    for name, config in smoothed.items():
        assert config.smoothing == "rts"
        assert config.replace(smoothing=trackers[name].smoothing) == trackers[name]
    assert smoothed_trackers(trackers, "default") == trackers
    plain = smoothed_trackers(trackers, "none")
    assert list(plain) == list(trackers)
    assert all(config.smoothing == "none" for config in plain.values())
    # the Fusion configurations are smoothed by their default, the PHD baseline is not
    assert smoothed_names(trackers) == [name for name in trackers if name != fusion.BASELINE]
    assert smoothed_names(plain) == []
    with pytest.raises(InputError, match="smoothing"):
        smoothed_trackers(trackers, "kalman")


@pytest.mark.parametrize("module", [hierarchical, fusion], ids=["hierarchical", "fusion"])
def test_the_experiment_runs_its_trackers_smoothed(module, monkeypatch, tmp_path):
    seen = {}

    def stand_in(sequences, trackers, out, seed=0, progress=False):
        seen.update(trackers)
        raise Captured
        yield  # pragma: no cover

    monkeypatch.setattr(module, "start_experiment", lambda *args: (0.0, tmp_path, None, []))
    monkeypatch.setattr(module, "frame_tracker_runs", stand_in)
    with pytest.raises(Captured):
        module.run_experiment(tmp_path, tmp_path, [101], smoothing="rts", progress=False)
    assert seen and all(config.smoothing == "rts" for config in seen.values())
    seen.clear()
    with pytest.raises(Captured):
        module.run_experiment(tmp_path, tmp_path, [101], smoothing="none", progress=False)
    assert seen and all(config.smoothing == "none" for config in seen.values())
    seen.clear()
    with pytest.raises(Captured):
        module.run_experiment(tmp_path, tmp_path, [101], progress=False)
    # the default: each configuration's own (the Fusion tracker's "rts", the others' "none")
    assert seen and all(
        config.smoothing == ("rts" if isinstance(config, FusionConfig) else "none")
        for config in seen.values()
    )
    assert any(isinstance(config, FusionConfig) for config in seen.values()) == (module is fusion)


def test_the_cmt_ablation_tables_its_trackers_smoothed(monkeypatch, tmp_path):
    seen = {}

    def stand_in(sequences, trackers, seed, progress):
        seen.update(trackers)
        raise Captured

    monkeypatch.setattr(cmt_ablation, "start_experiment", lambda *args: (0.0, tmp_path, None, []))
    monkeypatch.setattr(cmt_ablation, "ablation_table", stand_in)
    with pytest.raises(Captured):
        cmt_ablation.run_cmt_ablation(tmp_path, tmp_path, [101], smoothing="rts", progress=False)
    assert list(seen) == list(cmt_ablation.experiment_trackers())
    assert all(config.smoothing == "rts" for config in seen.values())


def test_an_unknown_smoothing_is_refused_before_any_run(tmp_path):
    for run in (hierarchical.run_experiment, fusion.run_experiment):
        with pytest.raises(InputError, match="smoothing"):
            run(tmp_path / "out", tmp_path, [101], smoothing="spline", progress=False)
        assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("name", "module", "function"),
    [
        ("hierarchical", hierarchical_experiment, "run_experiment"),
        ("fusion", fusion_experiment, "run_experiment"),
        ("cmt-ablation", cmt_command, "run_cmt_ablation"),
    ],
)
def test_the_option_reaches_the_experiment(
    name, module, function, monkeypatch, tmp_path, mot15_root
):
    seen = {}

    def stand_in(*args, **kwargs):
        seen.update(kwargs)
        raise Captured

    monkeypatch.setattr(module, function, stand_in)
    argv = ["experiment", name, "--out", str(tmp_path / "out"), "--quiet"]
    with pytest.raises(Captured):
        main([*argv, "--smoothing", "rts"])
    assert seen["smoothing"] == "rts"
    with pytest.raises(Captured):
        main([*argv, "--smoothing", "none"])
    assert seen["smoothing"] == "none"
    with pytest.raises(Captured):
        main(argv)
    assert seen["smoothing"] == "default"


@pytest.mark.parametrize("name", ["hierarchical", "fusion"])
def test_tracker_seeds_is_refused_where_it_would_be_ignored(name, tmp_path, capsys):
    argv = ["experiment", name, "--out", str(tmp_path / "out"), "--tracker-seeds", "3"]
    assert main(argv) == 2
    assert "unrecognized arguments: --tracker-seeds" in capsys.readouterr().err


def test_help_states_the_smoothing(capsys):
    for name in ("hierarchical", "fusion", "cmt-ablation"):
        with pytest.raises(SystemExit):
            main(["experiment", name, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "--smoothing {default,none,rts}" in text and "Rauch-Tung-Striebel" in text


def test_the_table_states_the_smoothing():
    assert smoothing_sentence({"smoothing": "none"}) == ""
    assert smoothing_sentence({}) == ""
    assert "`smoothing: rts`" in smoothing_sentence({"smoothing": "rts"})
    assert "Every tracker's" in smoothing_sentence({"smoothing": "rts", "smoothed": ["A"]})
    assert smoothing_sentence({"smoothing": "default", "smoothed": []}) == ""
    default = smoothing_sentence({"smoothing": "default", "smoothed": ["Naive fusion", "Proposed"]})
    assert "their configuration's default" in default and "Naive fusion, Proposed;" in default


def test_quick_hierarchical_run_smoothed_is_jaxtrack_track_smoothed(tmp_path, capsys, mot15_root):
    """The whole experiment end to end (its quick form), with ``--smoothing rts``: each
    result file is what ``jaxtrack track`` writes with the configuration's ``smoothing``,
    and each row's scores are ``jaxtrack eval``'s of that file."""
    out = tmp_path / "hier"
    argv = ["experiment", "hierarchical", "--out", str(out), "--quick", "--quiet"]
    assert main([*argv, "--smoothing", "rts"]) == 0
    capsys.readouterr()
    record = json.loads((out / "results.json").read_text())
    assert record["smoothing"] == "rts" and record["environment"] == environment()
    table = (out / "table.md").read_text()
    assert "`smoothing: rts`" in table and environment_line(record["environment"]) in table
    names = list(hierarchical.TRACKERS)
    assert [(r["sequence"], r["detections"], r["tracker"]) for r in record["rows"]] == [
        (sequence, source, name)
        for sequence in ("TUD-Campus", "video-101")
        for source in ("det", "bs")
        for name in names
    ]
    config = tmp_path / "full.json"
    config.write_text(json.dumps({"variant": "full", "smoothing": "rts"}))
    tracked = tmp_path / "tud.txt"
    folder = mot15_root / "TUD-Campus"
    argv = ["track", str(folder), "--tracker", "hierarchical", "--frames", "1:24"]
    assert main([*argv, "--config", str(config), "--out", str(tracked), "--quiet"]) == 0
    written = out / "sequences" / "TUD-Campus" / "det" / "full.txt"
    assert tracked.read_text() == written.read_text()
    capsys.readouterr()
    plain = tmp_path / "plain.txt"
    config.write_text(json.dumps({"variant": "full"}))
    assert main([*argv, "--config", str(config), "--out", str(plain), "--quiet"]) == 0
    assert plain.read_text() != written.read_text()  # the smoother moved the boxes
    capsys.readouterr()
    key = ("TUD-Campus", "det", "Hierarchical")
    row = next(r for r in record["rows"] if (r["sequence"], r["detections"], r["tracker"]) == key)
    assert main(["eval", str(folder), str(written), "--frames", "1:24", "--json"]) == 0
    scores = json.loads(capsys.readouterr().out)
    assert row["IDF1"] == pytest.approx(100 * scores["IDF1"], abs=0.006)
    assert row["MOTA"] == pytest.approx(100 * scores["MOTA"], abs=0.006)
