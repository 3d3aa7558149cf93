"""Experiment figures: the bars, lines and images drawn against the rows and grids given."""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.image import imread

from jaxtrack.experiments.magnitudes import MagnitudeSweep
from jaxtrack.plot.experiments import (
    ablation_figure,
    comparison_figure,
    save_ablation_figure,
    sweep_figure,
    sweep_heatmaps,
    tuning_figure,
)

SCORES = ("MOTA", "MOTP", "MODA", "MODP")


def _bar_heights(axes) -> list[list[float]]:
    """Heights of each bar container (one per series), in drawing order."""
    return [[bar.get_height() for bar in container] for container in axes.containers]


def _sweep() -> MagnitudeSweep:
    rates_r, rates_s = np.array([0.1, 1.0, 10.0]), np.array([0.02, 0.2])
    grid = np.arange(6.0).reshape(3, 2)
    scores = {
        "UM": {score: grid + k for k, score in enumerate(SCORES)},
        "GM": {score: 50 + grid - k for k, score in enumerate(SCORES)},
    }
    measured = {"lambda_r": 0.9, "lambda_s": 0.03}  # nearest grid point: (1, 0)
    return MagnitudeSweep(rates_r, rates_s, scores, [], measured, {})


def test_ablation_figure_draws_the_differences_of_every_variant_but_the_reference():
    rows = [
        {"variant": "UM", **{f"{s}_diff_pct": 0.0 for s in SCORES}},
        {"variant": "A1", "MOTA_diff_pct": 4.0, "MOTP_diff_pct": -2.0, "MODA_diff_pct": 1.5,
         "MODP_diff_pct": math.nan},
        {"variant": "GM", "MOTA_diff_pct": 9.0, "MOTP_diff_pct": 0.5, "MODA_diff_pct": -3.0,
         "MODP_diff_pct": 2.0},
    ]  # fmt: skip
    (axes,) = ablation_figure(rows, title="toy").axes
    assert axes.get_title() == "toy" and axes.get_ylabel() == "% difference w.r.t. UM"
    assert [label.get_text() for label in axes.get_xticklabels()] == ["A1", "GM"]
    assert [text.get_text() for text in axes.get_legend().get_texts()] == list(SCORES)
    # one container per score, one bar per variant; NaN is drawn as 0
    assert _bar_heights(axes) == [[4.0, 9.0], [-2.0, 0.5], [1.5, -3.0], [0.0, 2.0]]


def test_comparison_figure_has_one_panel_per_score_and_bars_per_tracker():
    rows = [
        {"sequence": "S1", "tracker": "PHD-GM", "MOTA": 60.0, "MOTP": 70.0},
        {"sequence": "S1", "tracker": "SORT", "MOTA": 50.0, "MOTP": 72.0},
        {"sequence": "S2", "tracker": "PHD-GM", "MOTA": 40.0, "MOTP": 65.0},
    ]
    figure = comparison_figure(rows, scores=("MOTA", "MOTP"), title="toy")
    assert figure.get_suptitle() == "toy"
    mota, motp = figure.axes
    assert mota.get_ylabel() == "MOTA (%)" and motp.get_ylabel() == "MOTP (%)"
    assert [label.get_text() for label in mota.get_xticklabels()] == ["S1", "S2"]
    # per tracker a container over the sequences; SORT has no S2 row: drawn as 0
    assert _bar_heights(mota) == [[60.0, 40.0], [50.0, 0.0]]
    assert _bar_heights(motp) == [[70.0, 65.0], [72.0, 0.0]]


def test_sweep_figure_draws_the_slices_through_the_measured_magnitudes():
    result = _sweep()
    figure = sweep_figure(result, scores=("MOTA", "MODA"), title="toy")
    assert figure.get_suptitle() == "toy: scores against the clutter and birth magnitudes"
    assert len(figure.axes) == 4
    top_mota, top_moda, bottom_mota, _ = figure.axes
    assert top_mota.get_xscale() == "log" and top_mota.get_title() == "lambda_s = 0.02"
    assert bottom_mota.get_title() == "lambda_r = 1"
    for variant, line in zip(("UM", "GM"), top_mota.lines, strict=True):
        assert line.get_label() == variant
        expected = np.column_stack([result.clutter_rates, result.scores[variant]["MOTA"][:, 0]])
        np.testing.assert_array_equal(line.get_xydata(), expected)
    um_moda = top_moda.lines[0].get_xydata()
    np.testing.assert_array_equal(um_moda[:, 1], result.scores["UM"]["MODA"][:, 0])
    gm_bottom = bottom_mota.lines[1].get_xydata()
    np.testing.assert_array_equal(gm_bottom[:, 0], result.birth_rates)
    np.testing.assert_array_equal(gm_bottom[:, 1], result.scores["GM"]["MOTA"][1, :])


def test_sweep_heatmaps_show_each_grid_and_star_its_best_point():
    result = _sweep()
    figure = sweep_heatmaps(result, title="toy")
    um, gm, colour_bar = figure.axes
    assert colour_bar.get_ylabel() == "MOTA (%)"
    for axes, variant in ((um, "UM"), (gm, "GM")):
        grid = result.scores[variant]["MOTA"]
        (image,) = axes.images
        np.testing.assert_array_equal(image.get_array(), grid)
        assert image.get_clim() == (0.0, 55.0)  # one colour scale over both grids
        (star,) = axes.lines
        np.testing.assert_array_equal(star.get_xydata(), [[1, 2]])  # column = lambda_s index
        assert axes.get_title() == f"{variant}: best MOTA {grid.max():.1f}"
        assert [text.get_text() for text in axes.texts] == [f"{v:.0f}" for v in grid.ravel()]


def test_tuning_figure_draws_losses_motas_and_the_grid_choice():
    steps = [
        {"dataset": "A", "step": 0, "MOTA": 30.0},
        {"dataset": "A", "step": 5, "MOTA": 45.0},
        {"dataset": "B", "step": 0, "MOTA": 20.0},
    ]
    losses = {"A": [3.0, 2.5, 2.0], "B": [5.0, 4.0]}
    summary = [
        {"dataset": "A", "method": "grid search", "MOTA": 50.0},
        {"dataset": "A", "method": "adam", "MOTA": 45.0},
        {"dataset": "B", "method": "grid search", "MOTA": 40.0},
    ]
    loss_a, loss_b, mota_a, mota_b = tuning_figure(steps, losses, summary).axes
    assert loss_a.get_title() == "A" and loss_b.get_title() == "B"
    np.testing.assert_array_equal(loss_b.lines[0].get_xydata(), [[0, 5.0], [1, 4.0]])
    motas, grid, fraction = mota_a.lines
    np.testing.assert_array_equal(motas.get_xydata(), [[0, 30.0], [5, 45.0]])
    assert grid.get_ydata()[0] == 50.0 and fraction.get_ydata()[0] == pytest.approx(47.5)
    assert grid.get_label() == "grid choice (50.0)" and fraction.get_linestyle() == "--"
    assert mota_b.lines[1].get_ydata()[0] == 40.0


def test_save_ablation_figure_writes_the_figure_at_100_dpi(tmp_path):
    rows = [{"variant": "GM", **{f"{s}_diff_pct": 10.0 * (k + 1) for k, s in enumerate(SCORES)}}]
    path = save_ablation_figure(rows, tmp_path / "a.png", ("MOTA",), title="t")
    assert path == tmp_path / "a.png"
    pixels = imread(path)
    assert pixels.shape[:2] == (450, 800)  # figsize (8, 4.5) inches at 100 dpi
    # the bar's colour (C0) is drawn
    assert np.any(np.all(np.abs(pixels[..., :3] - [0.122, 0.467, 0.706]) < 0.01, axis=-1))


def test_gain_figure_draws_mean_bars_min_max_marks_and_the_goal_line():
    from jaxtrack.plot.generalisation import gain_figure

    def row(group, variant, mean, low, high):
        return {"group": group, "variant": variant, "gain_pct_mean": mean,
                "gain_pct_min": low, "gain_pct_max": high}  # fmt: skip

    rows = [
        row("street", "UM", 0.0, 0.0, 0.0),
        row("street", "GM", 4.0, -2.0, 10.0),
        row("street", "GM+tuned", 6.0, 5.0, 7.0),
        row("PETS", "UM", 0.0, 0.0, 0.0),
        row("PETS", "GM", math.nan, math.nan, math.nan),
    ]
    (axes,) = gain_figure(rows, variants=("GM", "GM+tuned", "A1"), goal=9.0).axes
    assert [label.get_text() for label in axes.get_xticklabels()] == ["street", "PETS"]
    # A1 has no rows: not drawn; GM+tuned has no PETS row and GM's is NaN: drawn as 0
    legend = {text.get_text() for text in axes.get_legend().get_texts()}
    assert legend == {"GM", "GM+tuned", "goal +9 %"}
    bars = [container for container in axes.containers if hasattr(container, "patches")]
    assert [[bar.get_height() for bar in c] for c in bars] == [[4.0, 0.0], [6.0, 0.0]]
    # error marks from the min to the max gain over the seeds
    spans = [segment[:, 1] for segment in bars[0].errorbar.lines[2][0].get_segments()]
    assert [tuple(span) for span in spans] == [(-2.0, 10.0), (0.0, 0.0)]
    levels = [line.get_ydata() for line in axes.lines if line.get_linestyle() != "None"]
    assert sorted(float(y[0]) for y in levels) == [0.0, 9.0]  # the zero and goal lines
    # with the ceiling (a perfect tracker's gain over UM) in UM's rows, it is under the name
    rows[0]["gain_ceiling_pct"], rows[3]["gain_ceiling_pct"] = 7.33, math.nan
    (axes,) = gain_figure(rows).axes
    labels = [label.get_text() for label in axes.get_xticklabels()]
    assert labels == ["street\n(ceiling +7.3 %)", "PETS"]
