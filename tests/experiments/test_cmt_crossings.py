"""``jaxtrack experiment cmt-crossings``: the goal against hand counts, the figure against its
inputs, refusals, and (slow) the quick run's numbers recounted from its result files."""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.datasets import generate_video_scene
from jaxtrack.errors import InputError
from jaxtrack.experiments.cmt_ablation import crossing_counts
from jaxtrack.experiments.cmt_crossings import (
    COLUMNS,
    QUICK_SCENE,
    family_goal,
    run_crossing_families,
    variant_configs,
)
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.io import load_sequence
from jaxtrack.io.motchallenge import read_mot_file
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.metrics.reassociation import identity_cases
from jaxtrack.plot.cmt_analysis import crossing_families_figure

ROOT = Path(__file__).resolve().parents[2]


def test_the_goal_needs_fewer_swap_frames_with_com():
    ewom = {"crossing_swap_frames": 5, "crossing_frames": 40}
    fewer = family_goal("top", ewom, {"crossing_swap_frames": 4, "crossing_frames": 40}, 12, 3)
    assert (
        fewer["met"] and fewer["value"] == "5 -> 4 swap frames of 40 (12 scenes x 3 tracker seeds)"
    )
    for count in (5, 6):
        com = {"crossing_swap_frames": count, "crossing_frames": 40}
        assert not family_goal("top", ewom, com, 12, 3)["met"]
    none = {"crossing_swap_frames": 0, "crossing_frames": 40}
    assert not family_goal("both", none, none, 1, 1)["met"]  # no swap to remove: not shown


def test_figure_draws_its_inputs():
    rows = [
        {"family": f, "tracker": t, "SE_crossings": se, "crossing_swap_frames": n, **cases}
        for f, t, se, n, cases in [
            ("both", "MTb+CPD", 2.0, 4, {"kept": 3, "switched": 1, "lost": 0}),
            ("both", "CMT", 1.5, 3, {"kept": 2, "switched": 2, "lost": 0}),
            ("top", "MTb+CPD", 3.0, 6, {"kept": 0, "switched": 0, "lost": 0}),
            ("top", "CMT", 0.5, 1, {"kept": 1, "switched": 0, "lost": 1}),
        ]
    ]
    gaps = {"both": {"COM": 0.1, "EWOM": 0.05}, "top": {"COM": 0.6, "EWOM": 0.2}}
    figure = crossing_families_figure(rows, gaps)
    left, middle, right = figure.axes

    def heights(axes):
        return [patch.get_height() for patch in axes.patches]

    # bars: the first tracker's over the families, then the second's
    np.testing.assert_allclose(heights(left), [2.0, 3.0, 1.5, 0.5])
    np.testing.assert_allclose(heights(middle), [25.0, 0.0, 50.0, 0.0])
    np.testing.assert_allclose(heights(right), [0.05, 0.2, 0.1, 0.6])
    labels = [text.get_text() for text in middle.texts]
    assert labels == ["1/4", "0/0", "2/4", "0/2"]
    assert [text.get_text() for text in left.texts] == ["4", "6", "3", "1"]


def test_unknown_family_is_refused(tmp_path):
    with pytest.raises(InputError, match="unknown families"):
        run_crossing_families(tmp_path / "out", [1], ["top", "socks"], progress=False)
    assert not (tmp_path / "out").exists()


def test_script_runs_the_command(tmp_path):
    """``python experiments/cmt_crossings.py ARGS`` is ``jaxtrack experiment cmt-crossings``."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    script = ROOT / "experiments" / "cmt_crossings.py"
    argv = ["--out", str(tmp_path / "out"), "--families", "socks"]
    done = subprocess.run([sys.executable, script, *argv], env=env, capture_output=True, text=True)
    assert done.returncode == 2 and "--families" in done.stderr


def test_a_config_setting_the_variant_exits_2(tmp_path, capsys):
    config = tmp_path / "cmt.json"
    config.write_text(json.dumps({"variant": "mtb", "support": "box"}))
    argv = ["experiment", "cmt-crossings", "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*argv, "--config", str(config)]) == 2
    assert "leave the variant out" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_config_changes_both_variants_alike():
    configs = variant_configs(CMTConfig(support="box", appearance_weight=3.0))
    assert [c.variant for c in configs.values()] == ["cpd", "cmt"]
    for config in configs.values():
        assert (config.support, config.appearance_weight) == ("box", 3.0)
        assert config.max_components == CMTConfig().max_components
    quick = variant_configs(quick=True)
    assert quick["CMT"].overrides() == {"max_components": 8, "particles_per_component": 16}


@pytest.mark.slow
def test_quick_run_counts_what_its_result_files_hold(tmp_path, capsys):
    out = tmp_path / "crossings"
    argv = ["experiment", "cmt-crossings", "--out", str(out), "--quick", "--quiet"]
    assert main([*argv, "--families", "top", "--seeds", "224"]) == 0
    printed = capsys.readouterr().out
    record = json.loads((out / "results.json").read_text())
    assert printed.startswith("| " + " | ".join(COLUMNS) + " |")
    assert [(r["family"], r["tracker"]) for r in record["rows"]] == [
        ("top", "MTb+CPD"),
        ("top", "CMT"),
    ]
    folder = out / "scenes" / "top-224"
    loaded = load_sequence(folder)
    # the scene written is the family's (its people and boxes)
    scene = generate_video_scene(224, dataclasses.replace(QUICK_SCENE, crossing_alike="top"))
    np.testing.assert_array_equal(loaded.gt_table.boxes, scene.gt_table.boxes)
    (crossing,) = [e for e in scene.events if e.kind == "crossing"]
    crossings = [(crossing.ids, crossing.frames)]
    for row in record["rows"]:
        rows = read_mot_file(
            out / "sequences" / "top-224" / f"{row['tracker'].replace('+', '-')}.txt", "res"
        )
        counts = crossing_counts(loaded, rows, crossings)
        assert row["crossing_swap_frames"] == counts["crossing_swap_frames"]
        assert row["crossing_frames"] == counts["crossing_frames"]
        cases = identity_cases(rows, loaded.gt_table, [crossing])
        for outcome in ("kept", "switched", "lost"):
            assert row[outcome] == sum(c["outcome"] == outcome for c in cases)
        span = (loaded.first_frame, loaded.last_frame)
        summary = evaluate_sequence(loaded.gt_table, rows, span).summary()
        assert row["IDSW"] == summary["IDSW"]
        assert row["IDF1"] == pytest.approx(100 * summary["IDF1"], abs=0.01)
    cpd, cmt = record["rows"]
    assert record["goals"] == [family_goal("top", cpd, cmt, 1, 1)]
    assert set(record["fig9_gap"]["top"]) == {"COM", "EWOM", "COM_above"}
    assert (out / "crossings.png").stat().st_size > 10_000
    assert "## Goals" in (out / "table.md").read_text()
