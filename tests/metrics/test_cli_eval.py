"""``jaxtrack eval``: JSON contract, the three input forms, frame spans, errors (exit 2)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from jaxtrack.cli import main
from jaxtrack.io import read_mot_file, write_mot_file
from jaxtrack.metrics import combine_sequences, evaluate_sequence
from jaxtrack.metrics.synthetic import SCENARIOS, corrupt

#: The JSON keys of the issue's contract, in order.
JSON_KEYS = [
    "MOTA", "MOTP", "MODA", "MODP", "IDF1", "IDP", "IDR", "HOTA", "DetA", "AssA", "LocA",
    "FP", "FN", "IDSW", "Frag", "MT", "PT", "ML", "GT_IDs", "Recall", "Precision",
    "VACE_MOTA", "VACE_MODA", "VACE_MODP", "OSPA", "GOSPA", "OE", "DE", "SE",
]  # fmt: skip


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    code = main(["eval", *map(str, argv)])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture
def campus(mot15_root):
    folder = mot15_root / "TUD-Campus"
    return folder, folder / "ref_tracker_motmetrics.txt"


def test_acceptance_command_in_a_subprocess(campus):
    folder, result = campus
    completed = subprocess.run(
        [sys.executable, "-m", "jaxtrack.cli", "eval", str(folder), str(result), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    scores = json.loads(completed.stdout)
    assert list(scores) == JSON_KEYS
    expected = {"MOTA": 0.526462, "IDF1": 0.557659, "HOTA": 0.391397}
    for key, value in expected.items():
        assert round(scores[key], 6) == value, key
    counts = {"FP": 13, "FN": 150, "IDSW": 7, "Frag": 7, "MT": 1, "PT": 6, "ML": 1}
    assert {key: scores[key] for key in counts} == counts


def test_json_values_are_fractions_or_counts(capsys, campus):
    code, out, _ = run_cli(capsys, *campus, "--json")
    scores = json.loads(out)
    assert code == 0
    for key, value in scores.items():
        if key in ("FP", "FN", "IDSW", "Frag", "MT", "PT", "ML", "GT_IDs"):
            assert isinstance(value, int) and value >= 0, key
        elif key not in ("MOTA", "MODA", "VACE_MOTA", "VACE_MODA", "GOSPA"):
            assert 0.0 <= value <= 1.0, key


def test_gt_res_form_equals_sequence_form(capsys, campus):
    folder, result = campus
    _, from_folder, _ = run_cli(capsys, folder, result, "--json")
    code, explicit, _ = run_cli(
        capsys, "--gt", folder / "gt" / "gt.txt", "--res", result,
        "--seqinfo", folder / "seqinfo.ini", "--json",
    )  # fmt: skip
    assert code == 0
    assert json.loads(explicit) == json.loads(from_folder)


def test_frame_span(capsys, campus):
    folder, result = campus
    code, out, _ = run_cli(capsys, folder, result, "--frames", "10:40", "--json")
    assert code == 0
    gt = read_mot_file(folder / "gt" / "gt.txt", "gt", 71).frame_span(10, 40)
    res = read_mot_file(result, "res", 71).frame_span(10, 40)
    assert json.loads(out) == evaluate_sequence(gt, res, (10, 40)).summary()
    whole = json.loads(run_cli(capsys, folder, result, "--json")[1])
    assert json.loads(out)["FN"] < whole["FN"]


def test_options_reach_the_evaluation(capsys, campus):
    _, base, _ = run_cli(capsys, *campus, "--json")
    _, strict, _ = run_cli(capsys, *campus, "--json", "--iou-threshold", "0.7")
    _, ospa, _ = run_cli(capsys, *campus, "--json", "--ospa-c", "0.5", "--ospa-p", "2")
    _, centre, _ = run_cli(capsys, *campus, "--json", "--centre-threshold", "30")
    base, strict, ospa, centre = map(json.loads, (base, strict, ospa, centre))
    assert strict["MOTA"] < base["MOTA"] and strict["HOTA"] == base["HOTA"]
    assert ospa["OSPA"] != base["OSPA"] and ospa["MOTA"] == base["MOTA"]
    assert centre["MOTP"] != base["MOTP"]


def test_human_readable_output(capsys, campus):
    code, out, _ = run_cli(capsys, *campus)
    assert code == 0
    assert "MOTA" in out and "52.646 %" in out and "GOSPA_missed" in out


@pytest.fixture
def small_benchmark(tmp_path, mot15_root, mot15_gt):
    """A MOT root linking two shared sequences (no copies) and generated results."""
    root, results = tmp_path / "mot", tmp_path / "results"
    root.mkdir()
    for seed, name in enumerate(("KITTI-17", "TUD-Campus")):
        (root / name).symlink_to(mot15_root / name, target_is_directory=True)
        write_mot_file(
            results / f"{name}.txt", corrupt(mot15_gt[name][0], SCENARIOS["noisy"], seed)
        )
    return root, results


def test_benchmark_table_and_json(capsys, small_benchmark, mot15_gt):
    root, results = small_benchmark
    code, table, _ = run_cli(capsys, "--benchmark", root, "--results", results)
    assert code == 0
    lines = table.splitlines()
    assert lines[0].split()[:3] == ["Sequence", "HOTA", "DetA"]
    assert [line.split()[0] for line in lines[1:4]] == ["KITTI-17", "TUD-Campus", "COMBINED"]
    code, out, _ = run_cli(capsys, "--benchmark", root, "--results", results, "--json")
    report = json.loads(out)
    evaluations = [
        evaluate_sequence(
            mot15_gt[name][0],
            read_mot_file(results / f"{name}.txt", "res"),
            (1, mot15_gt[name][1]),
        )
        for name in ("KITTI-17", "TUD-Campus")
    ]
    assert list(report["sequences"]) == ["KITTI-17", "TUD-Campus"]
    assert report["sequences"]["KITTI-17"] == evaluations[0].summary()
    assert report["combined"] == combine_sequences(evaluations).summary()


def test_benchmark_missing_result_file(capsys, small_benchmark):
    root, results = small_benchmark
    (results / "TUD-Campus.txt").unlink()
    code, _, err = run_cli(capsys, "--benchmark", root, "--results", results)
    assert code == 2
    assert "TUD-Campus.txt" in err and "no result file" in err


def write_lines(path, lines):
    path.write_text("".join(line + "\n" for line in lines))
    return path


def test_result_frame_beyond_seq_length(capsys, campus, tmp_path):
    folder, result = campus
    lines = result.read_text().splitlines()
    bad = write_lines(tmp_path / "res.txt", [*lines[:5], "72,1,10,10,20,20,1,-1,-1,-1", *lines[5:]])
    code, out, err = run_cli(capsys, folder, bad, "--json")
    assert code == 2 and out == ""
    assert f"{bad}, line 6" in err and "72" in err
    assert "Traceback" not in err


def test_malformed_result_line(capsys, campus, tmp_path):
    folder, _ = campus
    bad = write_lines(
        tmp_path / "res.txt", ["1,1,10,10,20,20,1,-1,-1,-1", "2,1,10,ten,20,20,1,-1,-1,-1"]
    )
    code, _, err = run_cli(capsys, folder, bad)
    assert code == 2
    assert f"{bad}, line 2" in err


def test_distractor_rules_need_classes(capsys, campus):
    code, _, err = run_cli(capsys, *campus, "--distractors")
    assert code == 2
    assert "gt.txt, line 1" in err and "class" in err


@pytest.mark.parametrize(
    "argv",
    [
        [],
        ["only-one-argument"],
        ["--gt", "gt.txt"],
        ["--benchmark", "somewhere"],
        ["missing-folder", "res.txt"],
        ["--iou-threshold", "1.5", "x", "y"],
    ],
)
def test_bad_arguments_exit_2(capsys, argv):
    code, _, err = run_cli(capsys, *argv)
    assert code == 2
    assert err.startswith("jaxtrack eval: error:")


def test_missing_result_file_names_it(capsys, campus, tmp_path):
    folder, _ = campus
    code, _, err = run_cli(capsys, folder, tmp_path / "nope.txt")
    assert code == 2 and "nope.txt" in err and "not found" in err


def test_help(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["eval", "--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    for option in ("--benchmark", "--frames", "--iou-threshold", "--distractors", "--ospa-c"):
        assert option in out


def test_switches_listing_and_json(capsys, campus):
    # TUD-Campus's reference tracker: 7 identity switches, each listed once with a kind.
    folder, result = campus
    code, out, _ = run_cli(capsys, folder, result, "--switches")
    assert code == 0
    counts = dict(line.split() for line in out.splitlines() if line.startswith("IDSW_"))
    assert sum(map(int, counts.values())) == 7  # counts in the score listing, not percentages
    listing = out[out.index("identity switches (7):") :].splitlines()
    switch_lines = [line for line in listing if line.strip().startswith("frame")]
    assert len(switch_lines) == 7
    totals = dict(item.split() for item in listing[-1].strip().split(", "))
    assert sum(map(int, totals.values())) == 7
    code, out, _ = run_cli(capsys, folder, result, "--switches", "--json")
    report = json.loads(out)
    assert list(report)[:-1] == JSON_KEYS
    assert report["switches"]["counts"] == {kind: int(n) for kind, n in totals.items()}
    assert len(report["switches"]["rows"]) == report["IDSW"] == 7


def test_switches_refused_for_a_benchmark(capsys, small_benchmark):
    root, results = small_benchmark
    code, _, err = run_cli(capsys, "--benchmark", root, "--results", results, "--switches")
    assert code == 2 and "--switches" in err and "one sequence" in err


def test_errors_listing_and_json(capsys, campus):
    # TUD-Campus's reference tracker, sorted against the sequence's own detections
    folder, result = campus
    code, out, _ = run_cli(capsys, folder, result, "--errors", "--json")
    assert code == 0
    report = json.loads(out)
    assert sum(report["errors"]["FN"].values()) == report["FN"]
    assert sum(report["errors"]["FP"].values()) == report["FP"]
    det = folder / "det" / "det.txt"
    code, out, _ = run_cli(capsys, "--gt", folder / "gt" / "gt.txt", "--res", result,
                           "--errors", "--det", det)  # fmt: skip
    assert code == 0
    for name in ("FN", "FP"):
        total = report[name]
        assert f"{name} by what the detections offered ({total}):" in out
        for kind, n in report["errors"][name].items():
            assert any(line.split()[:2] == [kind, str(n)] for line in out.splitlines())


def test_errors_need_their_detections(capsys, campus, small_benchmark, tmp_path):
    folder, result = campus
    gt = folder / "gt" / "gt.txt"
    code, _, err = run_cli(capsys, "--gt", gt, "--res", result, "--errors")
    assert code == 2 and "--det" in err
    code, _, err = run_cli(capsys, folder, result, "--errors", "--det", tmp_path / "none.txt")
    assert code == 2 and "none.txt" in err and "not found" in err
    code, _, err = run_cli(capsys, folder, result, "--det", folder / "det" / "det.txt")
    assert code == 2 and "--errors" in err
    root, results = small_benchmark
    code, _, err = run_cli(capsys, "--benchmark", root, "--results", results, "--errors",
                           "--det", folder / "det" / "det.txt")  # fmt: skip
    assert code == 2 and "--det" in err and "det/det.txt" in err


def test_benchmark_errors_per_sequence_and_summed(capsys, small_benchmark):
    root, results = small_benchmark
    code, out, _ = run_cli(capsys, "--benchmark", root, "--results", results, "--errors", "--json")
    assert code == 0
    report = json.loads(out)
    errors = report["errors"]
    assert list(errors) == ["KITTI-17", "TUD-Campus", "COMBINED"]
    for name, scores in [*report["sequences"].items(), ("COMBINED", report["combined"])]:
        assert sum(errors[name]["FN"].values()) == scores["FN"]
        assert sum(errors[name]["FP"].values()) == scores["FP"]
    for side in ("FN", "FP"):
        for kind, n in errors["COMBINED"][side].items():
            assert n == errors["KITTI-17"][side][kind] + errors["TUD-Campus"][side][kind]
    code, table, _ = run_cli(capsys, "--benchmark", root, "--results", results, "--errors")
    assert code == 0
    lines = table[table.index("FN not_detected") - 30 :].splitlines()
    header = next(line for line in lines if "FN not_detected" in line)
    assert header.split()[0] == "Sequence"
    combined = next(line for line in lines if line.startswith("COMBINED") and "FN" not in line)
    row = [int(v) for v in combined.split()[1:]]
    assert row == [*errors["COMBINED"]["FN"].values(), *errors["COMBINED"]["FP"].values()]
