"""``jaxtrack experiment hierarchical``: its goals and table on a hand-made record (the runs
themselves are covered by tests/test_cli_hierarchical.py and tests/filters)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from jaxtrack.experiments.cmt_ablation import MOT15_COMBINED
from jaxtrack.experiments.common import ERROR_KEYS
from jaxtrack.experiments.frame_runs import SOURCES
from jaxtrack.experiments.hierarchical import RunKey, _table, goal_checks, table_markdown
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.metrics.events import KINDS
from jaxtrack.types import MotTable


def row(sequence, source, tracker, idf1, idsw):
    return {
        "sequence": sequence, "detections": source, "tracker": tracker, "synthetic": False,
        "MOTA": 50.0, "IDF1": idf1, "HOTA": 40.0, "IDSW": idsw, "Frag": 1, "MT": 1, "ML": 0,
    }  # fmt: skip


def event_counts(**counts) -> dict:
    """A kind's scores as :func:`~jaxtrack.metrics.events.score_events` gives them."""
    scored = counts["predicted"] - counts["ignored"]
    precision = counts["matched"] / max(1, scored)
    return {**counts, "precision": precision, "recall": counts["matched"] / counts["scripted"]}


def identity_counts(cases_kept: dict, lost: int = 0, unscored: int = 0) -> dict:
    """:func:`~jaxtrack.metrics.reassociation.identity_kept`'s output, from ``{kind: (cases,
    kept)}`` (kinds left out have no case); ``lost`` and ``unscored`` go to the occlusions."""
    out = {}
    for kind in ("occlusion", "crossing", "group"):
        cases, kept = cases_kept.get(kind, (0, 0))
        extra = (lost, unscored) if kind == "occlusion" else (0, 0)
        out[kind] = {"cases": cases, "kept": kept, "lost": extra[0], "unscored": extra[1]}
    out["overall"] = {key: sum(v[key] for v in out.values()) for key in out["occlusion"]}
    return out


def record(full_idsw, full_idf1, kept, matched):
    rows = []
    for source in ("det", "bs"):
        for name in ("A", "B", MOT15_COMBINED):
            rows.append(row(name, source, "Managed low level", 50.0, 10))
            rows.append(row(name, source, "Hierarchical", full_idf1, full_idsw))
    overall = event_counts(predicted=10, ignored=0, scripted=10, matched=matched)
    counts = identity_counts({"occlusion": (6, kept - 4), "group": (4, 4), "crossing": (4, 0)})
    return {
        "rows": rows,
        "events": {"s det": {kind: overall for kind in (*KINDS, "overall")} | {"tolerance": 25}},
        "event_tolerance_frames": 25,
        "identity_kept": {
            "s det Hierarchical": counts,
            "s det Managed low level": identity_counts({"occlusion": (6, 6), "group": (4, 4)}),
        },
    }


def test_goals_pass_and_fail_at_their_thresholds():
    goals = goal_checks(record(full_idsw=5, full_idf1=60.0, kept=9, matched=8), ["A", "B"])
    assert [g["pass"] for g in goals] == [True] * 5  # IDF1 60 > the best peer's 58.6
    goals = goal_checks(record(full_idsw=6, full_idf1=50.0, kept=8, matched=7), ["A", "B"])
    assert [g["pass"] for g in goals] == [False, False, False, False, False]
    # only the full tracker's identities count (the managed one kept 10 of 10), and only the
    # occlusions and group walks (the crossings' 0 of 4 are shown, not counted)
    assert goals[2]["measured"].startswith("8/10 cases (80.0%), 0 of them lost")
    assert goals[2]["measured"].endswith("crossings (not in the goal): 0/4")


def test_identity_goal_counts_lost_cases_and_shows_unscored_ones():
    data = record(full_idsw=5, full_idf1=60.0, kept=9, matched=8)
    data["identity_kept"]["s det Hierarchical"] = identity_counts(
        {"occlusion": (8, 5), "group": (4, 4)}, lost=3, unscored=2
    )
    goal = goal_checks(data, ["A", "B"])[2]
    assert not goal["pass"]  # 9 of 12: the 3 lost are failures
    assert goal["measured"].startswith("9/12 cases (75.0%), 3 of them lost")
    assert "2 unscored" in goal["measured"]


def test_event_goal_pools_the_runs_onsets_without_the_ignored_ones():
    data = record(full_idsw=5, full_idf1=60.0, kept=9, matched=8)
    a = event_counts(predicted=10, ignored=4, scripted=5, matched=5)  # precision 5 / 6
    b = event_counts(predicted=4, ignored=0, scripted=5, matched=4)  # precision 1
    data["events"] = {
        run: {kind: scores for kind in (*KINDS, "overall")} | {"tolerance": 25}
        for run, scores in (("s det", a), ("s bs", b))
    }
    (goal,) = [g for g in goal_checks(data, ["A", "B"]) if g["goal"].startswith("event")]
    # 9 matched of 14 - 4 scored onsets: 0.90 (9 / 14 = 0.64 would count ignored onsets)
    assert goal["pass"] and goal["measured"].startswith("precision 0.90 (9/10: 14 predicted")
    assert goal["measured"].endswith("recall 0.90 (9/10)")
    data["events"]["s bs"] = {k: event_counts(predicted=4, ignored=0, scripted=5, matched=2)
                              for k in (*KINDS, "overall")} | {"tolerance": 25}  # fmt: skip
    (goal,) = [g for g in goal_checks(data, ["A", "B"]) if g["goal"].startswith("event")]
    assert not goal["pass"] and "recall 0.70 (7/10)" in goal["measured"]


def test_goal_on_peers_uses_the_combined_mot15_row():
    goals = goal_checks(record(full_idsw=5, full_idf1=60.0, kept=9, matched=8), ["A", "B"])
    assert goals[-1]["measured"] == "60.0"


def test_table_markdown_lists_goals():
    data = record(full_idsw=5, full_idf1=60.0, kept=9, matched=8)
    data.update(synthetic_seeds_held_out=[101], seed=0, seconds=1.0)
    scores = event_counts(predicted=2, ignored=0, scripted=4, matched=2)
    data["events"] = {"s det": {k: scores for k in (*KINDS, "overall")} | {"tolerance": 25}}
    data["identity_kept"] = {"s det Hierarchical": identity_counts({"occlusion": (2, 1)})}
    data["goals"] = goal_checks(data, ["A", "B"])
    text = table_markdown(data)
    assert "| s det | 1.00 / 0.50 |" in text and "| s det Hierarchical | 1/2 |" in text
    assert text.count("FAIL") + text.count("PASS") == len(data["goals"])
    assert "Identity switches by kind" not in text  # rows without the kinds (older records)
    assert "did not keep" not in text  # no cases recorded (older records)
    case = {"kind": "occlusion", "person": 3, "frames": [10, 20], "before": 7}
    data["identity_cases"] = {
        "s det": [
            {**case, "after": 7, "outcome": "kept"},
            {**case, "person": 4, "after": 9, "outcome": "switched"},
            {**case, "person": 5, "after": None, "outcome": "lost"},
        ]
    }
    text = table_markdown(data)
    assert "| s det | occlusion 10-20 | 4 | 7 | 9 | switched |" in text
    assert "| s det | occlusion 10-20 | 5 | 7 | - | lost |" in text
    assert "| s det | occlusion 10-20 | 3 |" not in text  # kept: not listed
    kinds = {"IDSW_exchange": 2, "IDSW_drift": 1, "IDSW_takeover": 0, "IDSW_lost": 2}
    for r in data["rows"]:
        r.update(kinds, IDSW_replaced=r["IDSW"] - 5)
    text = table_markdown(data)
    assert "## Identity switches by kind" in text
    assert f"| {MOT15_COMBINED} | det | Hierarchical | 5 | 2 | 1 | 0 | 2 | 0 |" in text


def test_table_rows_carry_the_error_kinds_and_pooled_rows_sum_them():
    # one person tracked on 4 of 5 frames (1 FN), plus a false box on frame 1 (1 FP)
    boxes = lambda n, x: np.tile([x, 10.0, 20.0, 40.0], (n, 1))  # noqa: E731
    gt = MotTable.from_arrays(np.arange(1.0, 6.0), np.ones(5), boxes(5, 100.0))
    frames = np.array([1.0, 2.0, 3.0, 4.0, 1.0])
    result = MotTable.from_arrays(frames, np.array([1.0] * 4 + [2.0]), boxes(5, 100.0))
    result.boxes[4, 0] = 400.0
    evaluation = evaluate_sequence(gt, result, (1, 5))
    sequences = [SimpleNamespace(name=n, synthetic=False) for n in ("A", "B")]
    configs = {"Hierarchical": None}
    evaluations, errors = {}, {}
    for number, sequence in enumerate(sequences):
        for source in SOURCES:
            key = RunKey(sequence.name, source, "Hierarchical")
            evaluations[key] = evaluation
            errors[key] = {name: number + 2 * i for i, name in enumerate(ERROR_KEYS)}
    rows = _table(sequences, configs, evaluations, errors)
    by_key = {(r["sequence"], r["detections"]): r for r in rows}
    assert [by_key["B", "det"][name] for name in ERROR_KEYS] == [1 + 2 * i for i in range(8)]
    pooled = by_key[MOT15_COMBINED, "bs"]
    assert [pooled[name] for name in ERROR_KEYS] == [1 + 4 * i for i in range(8)]
    assert (pooled["IDSW"], by_key["A", "det"]["MOTA"]) == (0, 60.0)  # (5 - 1 FN - 1 FP) / 5
    text = table_markdown(
        {
            **record(full_idsw=5, full_idf1=60.0, kept=9, matched=8),
            "rows": rows,
            "synthetic_seeds_held_out": [101],
            "seed": 0,
            "seconds": 1.0,
            "goals": [],
        }
    )
    assert "## Misses and false positives by kind" in text
    assert (
        f"| {MOT15_COMBINED} | bs | Hierarchical | {' | '.join(str(1 + 4 * i) for i in range(8))} |"
        in text
    )
