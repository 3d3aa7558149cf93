"""``jaxtrack experiment fusion`` (and ``experiments/fusion.py``): the quick run's rows are
``jaxtrack eval``'s scores of the result files it writes (whole and held-out), its results
those of ``jaxtrack track``; refusals."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from jaxtrack.cli import main
from jaxtrack.experiments.common import ERROR_KEYS, SWITCH_KEYS, environment, environment_line
from jaxtrack.experiments.fusion import TABLE_COLUMNS, result_name
from jaxtrack.filters.fusion_tracker import FusionConfig

ROOT = Path(__file__).resolve().parents[1]


def _eval(folder: Path, result: Path, frames: str, capsys, det: Path) -> dict:
    argv = ["eval", str(folder), str(result), "--frames", frames, "--json"]
    assert main([*argv, "--errors", "--det", str(det)]) == 0
    return json.loads(capsys.readouterr().out)


def test_quick_run_scores_are_those_of_its_files(tmp_path, capsys, mot15_root):
    out = tmp_path / "fusion"
    assert main(["experiment", "fusion", "--out", str(out), "--quick", "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert printed.startswith("| " + " | ".join(TABLE_COLUMNS) + " |")
    record = json.loads((out / "results.json").read_text())
    rows = record["rows"]
    assert [(r["sequence"], r["detections"], r["scored"], r["tracker"]) for r in rows] == [
        (sequence, source, scored, tracker)
        for sequence in ("TUD-Campus", "video-101")
        for source in ("det", "bs")
        for scored in ("whole", "held-out")
        for tracker in ("Proposed", "PHD", "True identities")
    ]
    spans = {"trained": [1, 12], "held-out": [13, 24]}  # the first half of frames 1:24
    assert record["spans"] == {"TUD-Campus": spans, "video-101": spans}
    assert record["training"]["TUD-Campus det"].startswith("trained on frames 1:12")
    folders = {"TUD-Campus": mot15_root / "TUD-Campus", "video-101": out / "scenes" / "video-101"}
    for row in rows:
        result = out / "sequences" / row["sequence"] / row["detections"]
        result = result / f"{result_name(row['tracker'])}.txt"
        frames = "1:24" if row["scored"] == "whole" else "13:24"
        det = folders[row["sequence"]] / "det" / "det.txt"
        if row["detections"] == "bs":
            det = out / "sequences" / row["sequence"] / "bs" / "det.txt"
        scores = _eval(folders[row["sequence"]], result, frames, capsys, det)
        assert row["IDF1"] == pytest.approx(100 * scores["IDF1"], abs=0.006)
        assert row["MOTA"] == pytest.approx(100 * scores["MOTA"], abs=0.006)
        assert (row["MT"], row["PT"], row["ML"]) == (scores["MT"], scores["PT"], scores["ML"])
        assert (row["GT"], row["FM"], row["IDS"]) == (
            scores["GT_IDs"],
            scores["Frag"],
            scores["IDSW"],
        )
        assert row["MT %"] == round(100 * scores["MT"] / scores["GT_IDs"], 1)
        assert sum(row[key] for key in SWITCH_KEYS) == row["IDS"]
        # the error kinds are jaxtrack eval --errors's against the detections the run had
        kinds = scores["errors"]
        assert [row[key] for key in ERROR_KEYS] == [*kinds["FN"].values(), *kinds["FP"].values()]
        assert (
            sum(kinds["FN"].values()) == scores["FN"] and sum(kinds["FP"].values()) == scores["FP"]
        )
    # the reference: perfectly associated detections, no switch, no false positive
    oracle = [row for row in rows if row["tracker"] == "True identities"]
    assert len(oracle) == 8 and all(row["IDS"] == 0 and row["MT"] > 0 for row in oracle)
    # the bs detections are written beside the results and differ from MOT15's
    bs = (out / "sequences" / "TUD-Campus" / "bs" / "det.txt").read_text()
    assert bs and bs != (mot15_root / "TUD-Campus" / "det" / "det.txt").read_text()
    # a result is what ``jaxtrack track`` writes with the same configuration and seed
    config = tmp_path / "fusion.json"
    config.write_text(json.dumps(FusionConfig().to_dict()))
    tracked = tmp_path / "tud.txt"
    argv = ["track", str(folders["TUD-Campus"]), "--tracker", "fusion", "--frames", "1:24"]
    assert main([*argv, "--config", str(config), "--out", str(tracked), "--quiet"]) == 0
    written = out / "sequences" / "TUD-Campus" / "det" / "proposed.txt"
    assert tracked.read_text() == written.read_text()
    table = (out / "table.md").read_text()
    assert table.startswith("# Fusion tracker") and "Quick smoke run" in table
    # what produced the numbers: this checkout's commit and the packages' versions
    assert record["environment"] == environment()
    assert environment_line(record["environment"]) in table
    # the Fusion tracker's offline output is smoothed by its default, the PHD tracker's not
    assert record["smoothing"] == "default" and record["smoothed"] == ["Proposed"]
    assert "Smoothed by their configuration's default" in table and "Proposed;" in table
    assert "## Identity switches by kind" in table
    assert "## Misses and false positives by kind" in table
    assert "| Proposed (paper, Table 4) | 94.7 | 5.3 | 0.0 | 18 | 1 | 0 | 19 | 34 | 7 |" in table
    # quick: the scene's goal only (no PETS, no ablation, no pooled MOT15 row)
    assert [g["goal"].split(" (")[0] for g in record["goals"]] == ["video-101", "video-101"]
    assert table.count("- PASS") + table.count("- FAIL") == 2


def test_missing_data_exits_2(tmp_path, capsys):
    argv = ["experiment", "fusion", "--out", str(tmp_path / "out"), "--quick"]
    assert main([*argv, "--data", str(tmp_path / "none"), "--quiet"]) == 2
    error = capsys.readouterr().err
    assert "MOT15 sequence not found" in error and str(tmp_path / "none") in error


def test_script_runs_the_command(tmp_path):
    """``python experiments/fusion.py ARGS`` is ``jaxtrack experiment fusion ARGS``."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    script = ROOT / "experiments" / "fusion.py"
    argv = [sys.executable, script, "--out", str(tmp_path / "out"), "--seeds", "-1"]
    done = subprocess.run(argv, env=env, capture_output=True, text=True)
    assert done.returncode == 2 and "--seeds" in done.stderr


def test_help_says_what_is_compared(capsys):
    with pytest.raises(SystemExit) as done:
        main(["experiment", "fusion", "--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "Detector, Classifier, Predictor" in text and "the paper's protocol" in text
    assert "IDF1 > 58.6 and MT > 25" in text
