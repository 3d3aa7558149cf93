"""``jaxtrack experiment fusion``: a row's trajectory scores on a hand-counted case, the
held-out span, the goals at their thresholds and the table, on hand-made rows (the runs
themselves: tests/test_cli_fusion_experiment.py)."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.experiments.cmt_ablation import MOT15_COMBINED, SYNTHETIC_COMBINED
from jaxtrack.experiments.fusion import (
    ABLATION,
    BEST_PEER_MT,
    PAPER_PROTOCOL,
    PAPER_TABLE4_COUNTS,
    TABLE_COLUMNS,
    RunKey,
    experiment_trackers,
    goal_checks,
    held_out_frames,
    result_name,
    score_row,
    table_markdown,
    with_init_rule,
)
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.io import load_sequence
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.types import MotTable


def _table(rows) -> MotTable:
    frames, ids, x = (np.array(column, float) for column in zip(*rows, strict=True))
    boxes = np.stack([x, np.full_like(x, 10.0), np.full_like(x, 20.0), np.full_like(x, 40.0)], 1)
    return MotTable.from_arrays(frames, ids, boxes)


def test_score_row_on_a_hand_counted_case():
    # three people in 10 frames, far apart: A tracked throughout (MT), B on frames 1-3 by
    # track 2 then 7-8 by track 3 (5/10: PT; one fragmentation, one identity switch), C on
    # frame 1 only (1/10: ML)
    gt = _table([(k, person, 100.0 * person) for k in range(1, 11) for person in (1, 2, 3)])
    tracked = [(k, 1, 100.0) for k in range(1, 11)]
    tracked += [(k, 2, 200.0) for k in (1, 2, 3)] + [(k, 3, 200.0) for k in (7, 8)]
    tracked += [(1, 4, 300.0)]
    evaluation = evaluate_sequence(gt, _table(tracked), (1, 10))
    row = score_row(RunKey("S", "det", "whole", "Proposed"), False, evaluation)
    assert [row[c] for c in TABLE_COLUMNS[:4]] == ["S", "det", "whole", "Proposed"]
    assert (row["MT %"], row["PT %"], row["ML %"]) == (33.3, 33.3, 33.3)
    assert (row["MT"], row["PT"], row["ML"], row["GT"], row["FM"], row["IDS"]) == (1, 1, 1, 3, 1, 1)
    assert row["MOTA"] == 50.0  # (16 matches - 0 FP - 1 IDS) / 30 gt boxes


def test_held_out_frames_follow_the_default_training_span(mot15_root):
    tud = load_sequence(mot15_root / "TUD-Campus")  # 71 frames: trained on 1:36
    assert held_out_frames(tud) == (37, 71)
    span = load_sequence(mot15_root / "TUD-Campus", (11, 30))  # trained on 11:20
    assert held_out_frames(span) == (21, 30)
    with pytest.raises(InputError, match="no frame is left after the training span"):
        held_out_frames(load_sequence(mot15_root / "TUD-Campus", (5, 5)))


def test_trackers_are_the_paper_s_ablation_and_the_phd_baseline():
    trackers = experiment_trackers()
    assert list(trackers) == [
        "Detector",
        "Classifier",
        "Predictor",
        "Naive fusion",
        "Proposed",
        "PHD",
    ]
    assert [trackers[name].pool for name in list(ABLATION)[:3]] == [
        "detection",
        "classifier",
        "predictor",
    ]
    assert trackers["Naive fusion"] == FusionConfig(fusion="naive")
    assert trackers["Proposed"] == FusionConfig() and trackers["PHD"] == PHDConfig()
    assert list(experiment_trackers(quick=True)) == ["Proposed", "PHD"]
    assert result_name("Naive fusion") == "naive-fusion"


def test_the_init_rule_reaches_every_fusion_configuration_only():
    trackers = experiment_trackers()
    costed = with_init_rule(trackers, "cost")
    assert list(costed) == list(trackers)
    for name, config in costed.items():
        if name == "PHD":
            assert config == trackers[name]
        else:
            assert config == trackers[name].replace(init_rule="cost")
    assert with_init_rule(trackers, "share") == trackers
    with pytest.raises(InputError, match="init_rule"):
        with_init_rule(trackers, "median")


def test_an_unknown_init_rule_is_refused_before_any_output(tmp_path):
    from jaxtrack.experiments.fusion import run_experiment

    with pytest.raises(InputError, match="init_rule"):
        run_experiment(tmp_path / "out", tmp_path, [101], init_rule="median", progress=False)
    assert not (tmp_path / "out").exists()


def test_the_command_passes_the_init_rule(monkeypatch, tmp_path, capsys):
    from jaxtrack.cli import main
    from jaxtrack.commands import fusion_experiment

    seen = {}

    def fake(out, data, seeds, **options):
        seen.update(options)
        return {"rows": [], "goals": []}

    monkeypatch.setattr(fusion_experiment, "run_experiment", fake)
    argv = ["experiment", "fusion", "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*argv, "--init-rule", "cost"]) == 0
    assert seen["init_rule"] == "cost"
    assert main(argv) == 0 and seen["init_rule"] == "share"
    capsys.readouterr()
    assert main([*argv, "--init-rule", "median"]) == 2
    assert "--init-rule: invalid choice: 'median'" in capsys.readouterr().err


def row(sequence, source, scored, tracker, synthetic=False, **values):
    base = {"MT": 10, "PT": 0, "ML": 0, "GT": 10, "FM": 5, "IDS": 5, "IDF1": 50.0}
    base.update(values)
    base["MT %"] = round(100 * base["MT"] / base["GT"], 1)
    base.update({"PT %": 0.0, "ML %": 0.0, "MOTA": 50.0, "HOTA": 40.0})
    keys = {"sequence": sequence, "detections": source, "scored": scored, "tracker": tracker}
    return {**keys, "synthetic": synthetic, **base}


def pets_rows(**proposed):
    rows = [row("PETS09-S2L1", s, p, "Proposed", GT=19, MT=17) for s in ("det", "bs")
            for p in ("whole", "held-out")]  # fmt: skip
    rows[0] = row("PETS09-S2L1", "det", "whole", "Proposed", **{"GT": 19, **proposed})
    return rows


@pytest.mark.parametrize(
    ("values", "met"),
    [
        ({"MT": 18, "ML": 0, "IDS": 7, "FM": 34}, True),
        ({"MT": 17, "ML": 0, "IDS": 0, "FM": 0}, False),
        ({"MT": 18, "ML": 1, "IDS": 0, "FM": 0}, False),
        ({"MT": 18, "ML": 0, "IDS": 8, "FM": 0}, False),
        ({"MT": 18, "ML": 0, "IDS": 0, "FM": 35}, False),
    ],
)
def test_table4_goal_at_its_thresholds(values, met):
    (goal,) = goal_checks(pets_rows(**values))
    assert goal["pass"] is met
    assert goal["goal"].startswith(f"PETS09-S2L1 (det, {PAPER_PROTOCOL}: the paper's protocol)")
    assert "MT >= 18/19, ML 0, IDS <= 7, FM <= 34" in goal["goal"]
    # the video detector's and the held-out scores are reported beside
    parts = goal["measured"].split("; ")
    assert [p.split(":")[0] for p in parts] == [
        "det whole",
        "det held-out",
        "bs whole",
        "bs held-out",
    ]
    assert parts[2] == "bs whole: MT 17/19 (89.5%), PT 0, ML 0, FM 5, IDS 5"


def test_table4_goal_rounds_the_paper_s_share_up():
    # 94.7 % of 12 trajectories is 11.4: 11 of 12 (91.7 %) is below the paper's share
    rows = [row("PETS09-S2L1", "det", "whole", "Proposed", GT=12, MT=11, ML=0, IDS=0, FM=0)]
    (goal,) = goal_checks(rows)
    assert not goal["pass"] and "MT >= 12/12" in goal["goal"]
    rows[0]["MT"] = 12
    assert goal_checks(rows)[0]["pass"]


def ablation_rows(sequence, mt, errors):
    """Rows of the five ablation trackers: ``mt`` and ``errors`` (IDS, FM) by name."""
    return [
        row(sequence, "det", "whole", name, MT=mt[name], IDS=errors.get(name, (5, 5))[0],
            FM=errors.get(name, (5, 5))[1])
        for name in ABLATION
    ]  # fmt: skip


def test_ablation_goals_on_every_sequence():
    good = {"Detector": 8, "Classifier": 3, "Predictor": 1, "Naive fusion": 8, "Proposed": 9}
    rows = ablation_rows("A", good, {"Proposed": (2, 3), "Naive fusion": (3, 3)})
    rows += ablation_rows("B", good, {"Proposed": (1, 1), "Naive fusion": (1, 2)})
    rows += ablation_rows(MOT15_COMBINED, {name: 0 for name in good}, {})  # not a sequence
    mt_goal, error_goal, peer_goal = goal_checks(rows)
    assert peer_goal["goal"].startswith(MOT15_COMBINED)
    assert mt_goal["pass"] and error_goal["pass"]
    assert mt_goal["measured"] == "A: 9 >= 8 >= 8 (Detector); B: 9 >= 8 >= 8 (Detector)"
    assert error_goal["measured"] == "A: 2 + 3 < 3 + 3; B: 1 + 1 < 1 + 2"
    # a naive fusion below the best member on one sequence; equal errors on the other
    worse = {**good, "Classifier": 9}
    rows = ablation_rows("A", worse, {"Proposed": (2, 3), "Naive fusion": (3, 3)})
    rows += ablation_rows("B", good, {"Proposed": (1, 2), "Naive fusion": (1, 2)})
    mt_goal, error_goal = goal_checks(rows)
    assert not mt_goal["pass"] and not error_goal["pass"]
    assert mt_goal["measured"].startswith("A: 9 >= 8 >= 9 (Classifier)")


@pytest.mark.parametrize(
    ("idf1", "mt", "met"),
    [(58.7, BEST_PEER_MT + 1, True), (58.6, BEST_PEER_MT + 1, False), (70.0, BEST_PEER_MT, False)],
)
def test_peer_goal_is_strictly_above_the_best_peer(idf1, mt, met):
    rows = [row(MOT15_COMBINED, "det", "whole", "Proposed", IDF1=idf1, MT=mt, GT=60)]
    rows.append(row(MOT15_COMBINED, "det", "held-out", "Proposed", IDF1=99.0, MT=60, GT=60))
    (goal,) = goal_checks(rows)
    assert goal["pass"] is met and goal["measured"] == f"IDF1 {idf1}, MT {mt}"


def test_baseline_goal_judges_the_pooled_scenes_held_out():
    rows = []
    for name, proposed, phd in (
        ("s1", 60.0, 70.0),
        ("s2", 80.0, 50.0),
        (SYNTHETIC_COMBINED, 70.0, 60.0),
    ):
        for scored, shift in (("held-out", 0.0), ("whole", -50.0)):
            rows.append(row(name, "bs", scored, "Proposed", True, IDF1=proposed + shift))
            rows.append(row(name, "bs", scored, "PHD", True, IDF1=phd))
    (goal,) = goal_checks(rows)
    assert goal["pass"] and goal["goal"].startswith(f"{SYNTHETIC_COMBINED} (bs, held-out)")
    assert (
        goal["measured"] == "s1: 60.0 vs 70.0; s2: 80.0 vs 50.0; synthetic combined: 70.0 vs 60.0"
    )
    (goal,) = goal_checks(rows[:4])  # one scene: judged on it
    assert not goal["pass"] and goal["goal"].startswith("s1 (bs, held-out)")


def test_table_markdown_puts_table4_beside_ours_and_lists_goals():
    rows = pets_rows(MT=18, ML=0, IDS=3, FM=20)
    record = {
        "quick": False,
        "seed": 0,
        "synthetic_seeds_held_out": [101],
        "spans": {"PETS09-S2L1": {"trained": [1, 398], "held-out": [399, 795]}},
        "training": {"PETS09-S2L1 det": "trained on frames 1:398"},
        "rows": rows,
        "paper_table1": [],
        "peers": [],
        "goals": goal_checks(rows),
        "tracking_seconds": {"Proposed": 10.0},
        "frames_per_s": {"Proposed": 79.5},
        "seconds": 20.0,
    }
    text = table_markdown(record)
    counts = " | ".join(map(str, PAPER_TABLE4_COUNTS.values()))
    assert f"| Proposed (paper, Table 4) | 94.7 | 5.3 | 0.0 | {counts} | 34 | 7 |" in text
    assert "| Proposed, det, whole (the paper's protocol) | 94.7 | 0.0 | 0.0 | 18 |" in text
    assert "| Proposed, bs, held-out | 89.5 |" in text
    assert "PETS09-S2L1 1:398 (held out 399:795)" in text
    assert "- PASS: PETS09-S2L1 (det, whole" in text and text.count("PASS") == 1
    assert "Proposed 10.0 (79.5 frames/s)" in text
    assert "cost rule" not in text
    assert "th_init is calibrated by the cost rule" in table_markdown(
        {**record, "init_rule": "cost"}
    )
