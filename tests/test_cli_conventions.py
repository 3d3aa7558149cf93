"""One CLI convention (DESIGN.md, Style): a shared flag means the same in every command."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from jaxtrack import cli
from jaxtrack.cli import COMMANDS, main
from jaxtrack.commands.arguments import (
    CONFIG_HELP,
    FRAMES_HELP,
    JSON_HELP,
    QUIET_HELP,
    SEED_HELP,
    SEED_TYPE,
)
from tests.test_cli_detect import person_box, write_synthetic_folder

#: Commands that show progress bars (or step messages) and so take --quiet.
WITH_PROGRESS = (
    "demo",
    "track",
    "learn-context",
    "learn-zones",
    "tune",
    "detect",
    "track-video",
    "experiment context-ablation",
    "experiment context-gap",
    "experiment context-generalisation",
    "experiment sweep-magnitudes",
    "experiment compare-trackers",
    "experiment cmt-crossings",
    "experiment cmt-ablation",
    "experiment hierarchical",
    "experiment hierarchical-noise",
    "experiment fusion",
    "experiment gradient-tuning",
    "simulate",  # with --video
)
#: Commands that print results and so take --json.
WITH_JSON = ("inspect", "track", "eval", "learn-context", "learn-zones", "tune", "detect")


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (action,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(action.choices)


def _parsers() -> dict[str, argparse.ArgumentParser]:
    """Every command's parser by its name (``experiment NAME`` for the experiments)."""
    parsers = {}
    for name, parser in _subparsers(cli.build_parser()).items():
        if name == "experiment":
            for sub, sub_parser in _subparsers(parser).items():
                parsers[f"experiment {sub}"] = sub_parser
        else:
            parsers[name] = parser
    return parsers


PARSERS = _parsers()


def _option(parser: argparse.ArgumentParser, flag: str) -> argparse.Action | None:
    return next((a for a in parser._actions if flag in a.option_strings), None)


def test_every_command_module_is_registered():
    names = {name.split()[0] for name in PARSERS}
    assert names == {name.replace("_", "-") for name in COMMANDS}


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_shared_flags_mean_the_same(name):
    parser = PARSERS[name]
    seed = _option(parser, "--seed")
    if seed is not None:
        assert seed.default == 0 and seed.type is SEED_TYPE and seed.help == SEED_HELP
    frames = _option(parser, "--frames")
    if frames is not None:
        # a span string, read by jaxtrack.io.parse_frame_span: never a count
        assert frames.help == FRAMES_HELP and frames.metavar == "A:B" and frames.type is None
    config = _option(parser, "--config")
    if config is not None:
        assert config.help == CONFIG_HELP
    for flag, help_text in (("--quiet", QUIET_HELP), ("--json", JSON_HELP)):
        option = _option(parser, flag)
        if option is not None:
            assert option.help == help_text and option.default is False
    assert (_option(parser, "--quiet") is not None) == (name in WITH_PROGRESS), name
    assert (_option(parser, "--json") is not None) == (name in WITH_JSON), name


def test_simulate_counts_frames_with_num_frames():
    parser = PARSERS["simulate"]
    assert _option(parser, "--frames") is None and _option(parser, "--config") is None
    assert _option(parser, "--num-frames").type("12") == 12
    assert _option(parser, "--scene-config") is not None


def test_experiment_help_lists_each_experiment(capsys):
    with pytest.raises(SystemExit):
        main(["experiment", "--help"])
    text = capsys.readouterr().out
    for name in (
        "context-ablation",
        "context-gap",
        "sweep-magnitudes",
        "compare-trackers",
        "gradient-tuning",
    ):
        assert name in text


def _json_out(capsys) -> dict:
    """The single JSON object printed on stdout."""
    result = json.loads(capsys.readouterr().out)
    assert isinstance(result, dict)
    return result


def test_inspect_and_eval_json(mot15_root, capsys):
    sequence = mot15_root / "TUD-Campus"
    assert main(["inspect", str(sequence), "--frames", "1:20", "--json"]) == 0
    summary = _json_out(capsys)
    assert summary["frames"] == 20 and {"precision", "recall"} <= summary.keys()
    gt = str(sequence / "gt" / "gt.txt")
    assert main(["eval", "--gt", gt, "--res", gt, "--frames", "1:20", "--json"]) == 0
    assert _json_out(capsys)["MOTA"] == 1.0


def test_track_and_tune_json(mot15_root, tmp_path, capsys):
    sequence = str(mot15_root / "TUD-Campus")
    small = tmp_path / "small.json"
    small.write_text(json.dumps({"num_particles": 128, "births_per_detection": 4}))
    out = tmp_path / "t.txt"
    argv = ["track", sequence, "--frames", "1:20", "--config", str(small), "--out", str(out)]
    assert main([*argv, "--json"]) == 0
    summary = _json_out(capsys)
    assert summary["out"] == str(out) and summary["frames"] == 20
    assert summary["rows"] == len(out.read_text().splitlines()) and summary["seconds"] > 0

    tuned = tmp_path / "tuned.json"
    small_tuning = [
        "--steps",
        "1",
        "--keys",
        "1",
        "--particles",
        "64",
        "--births-per-detection",
        "2",
    ]
    argv = ["tune", sequence, "--frames", "1:20", "--out", str(tuned), *small_tuning]
    assert main([*argv, "--quiet", "--json"]) == 0
    report = _json_out(capsys)
    assert report["out"] == str(tuned) and report["steps"] == 1
    assert {"start", "tuned", "config", "history"} <= report.keys()
    assert report == {
        "out": str(tuned),
        "report_file": str(tmp_path / "tuned.tuning.json"),
        **json.loads((tmp_path / "tuned.tuning.json").read_text()),
    }


def test_learn_context_json(mot15_root, tmp_path, capsys):
    out = tmp_path / "ctx.npz"
    sequence = str(mot15_root / "TUD-Campus")
    argv = ["learn-context", sequence, "--birth-from", "gt", "--out", str(out)]
    assert main([*argv, "--quiet", "--json"]) == 0
    summary = _json_out(capsys)
    assert summary["out"] == str(out) and summary["frames"] == [1, 71]
    assert summary["birth"]["source"] == "gt" and summary["clutter"]["num_events"] > 0


def test_detect_json_with_gt(tmp_path, capsys):
    folder = write_synthetic_folder(tmp_path / "img1")
    gt = tmp_path / "gt.txt"
    gt.write_text(
        "".join(f"{k},1,{','.join(map(str, person_box(k)))},1,1,1\n" for k in range(1, 41))
    )
    out = tmp_path / "det.txt"
    argv = ["detect", str(folder), "--out", str(out), "--no-split", "--gt", str(gt)]
    assert main([*argv, "--quiet", "--json"]) == 0
    summary = _json_out(capsys)
    assert summary["out"] == str(out) and summary["frames"] == [1, 40]
    assert summary["detections"] == len(out.read_text().splitlines())
    assert 0.9 <= summary["precision"] <= 1 and 0.9 <= summary["recall"] <= 1
    assert np.isfinite(summary["frames_per_second"])
