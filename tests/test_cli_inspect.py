"""The CLI: help, inspect on real data, bad input reported with file and line (exit 2)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from jaxtrack.cli import main


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "jaxtrack", *args], capture_output=True, text=True, check=False
    )


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for command in ("simulate", "inspect", "eval"):
        assert command in out


def test_inspect_pets_json(mot15_root, capsys):
    assert main(["inspect", str(mot15_root / "PETS09-S2L1"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["frames"] == 795
    assert summary["detections"] == 4359
    assert summary["gt_ids"] == 19
    assert summary["gt_boxes"] == 4650 and summary["gt_ignored_boxes"] == 174
    assert 0.7 < summary["precision"] < 0.9 and 0.7 < summary["recall"] < 0.9


def test_inspect_precision_recall_of_gt_against_itself(mot15_root, tmp_path, capsys):
    seq = tmp_path / "seq"
    shutil.copytree(mot15_root / "TUD-Campus", seq)
    (seq / "det" / "det.txt").chmod(0o644)
    shutil.copy(seq / "gt" / "gt.txt", seq / "det" / "det.txt")
    assert main(["inspect", str(seq), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["precision"] == 1.0 and summary["recall"] == 1.0


def test_inspect_frame_span_and_text_output(mot15_root, capsys):
    assert main(["inspect", str(mot15_root / "PETS09-S2L1"), "--frames", "401:795"]) == 0
    out = capsys.readouterr().out
    assert "395  (401..795)" in out and "precision" in out


def test_bad_detection_file_exit_2_without_traceback(mot15_root, tmp_path):
    seq = tmp_path / "bad"
    shutil.copytree(mot15_root / "PETS09-S2L1", seq)
    det = seq / "det" / "det.txt"
    det.chmod(0o644)
    det.write_text("1,-1,10,10,-5,20,0.9,-1,-1,-1\n")
    result = run_cli("inspect", str(seq), "--json")
    assert result.returncode == 2
    assert f"{det}, line 1: w -5 is below 1 pixel" in result.stderr
    assert "Traceback" not in result.stderr and result.stdout == ""


def test_bad_frame_span_exit_2(mot15_root, capsys):
    assert main(["inspect", str(mot15_root / "TUD-Campus"), "--frames", "5:900"]) == 2
    assert "1 <= start <= end <= 71" in capsys.readouterr().err
