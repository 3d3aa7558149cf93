"""``jaxtrack demo``: the toolkit's main job, end to end, on the embedded synthetic scene.

1. simulate the default surveillance scene of a seed (:mod:`jaxtrack.datasets.synthetic`: 800
   frames, entry zones, localised clutter sources; the true intensities are known);
2. learn the birth and clutter intensities on the first half (births from a UM tracker run,
   clutter from the ground truth; :func:`~jaxtrack.context.learn.learn_context`);
3. track the second half with uniform intensities (UM) and with the learned context (GM),
   score both (MOTA, MOTP, MODA, MODP, IDF1, HOTA);
4. sweep the clutter and birth magnitudes over a small log-spaced grid for UM and GM in one
   vmapped call (:func:`~jaxtrack.experiments.magnitudes.magnitude_sweep`);
5. write the figures: ``demo.png`` (learned intensities and MOTA against the magnitudes),
   ``intensities.png`` (learned vs true intensities), ``sweep.png``, ``sweep_mota.png``,
   ``tracks.png`` (particles, estimates and tracks over a test frame), plus ``results.csv``,
   ``sweep.csv``, the tracker outputs ``UM.txt`` / ``GM.txt`` and ``summary.md``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import jax
import numpy as np

from jaxtrack.datasets.context_truth import load_context_truth
from jaxtrack.experiments.common import (
    COUNT_KEYS,
    QUICK_TRACKER_CONFIG,
    SCORE_KEYS,
    evaluate_rows,
    learn_split,
    markdown_table,
    output_folder,
    score_summary,
    split_halves,
    synthetic_sequence,
    write_csv,
)
from jaxtrack.experiments.magnitudes import (
    MagnitudeSweep,
    magnitude_sweep,
    sweep_summary,
    variant_params,
    write_sweep_files,
)
from jaxtrack.filters.phd_tracker import Context, PHDConfig, phd_filter_of
from jaxtrack.io.motchallenge import write_results
from jaxtrack.pipelines.sweep import log_grid
from jaxtrack.pipelines.tracking import phd_frame_snapshot, track_sequences
from jaxtrack.plot.context import save_context_plots
from jaxtrack.plot.experiments import save_demo_figure
from jaxtrack.plot.tracks import phd_frame_figure

#: The demo's magnitude grid: ``lambda_r`` (false detections / frame) x ``lambda_s``
#: (births / frame), log-spaced.
DEMO_CLUTTER_RATES = log_grid(0.1, 10.0, 5)
DEMO_BIRTH_RATES = log_grid(0.02, 2.0, 5)
#: The 2 x 2 grid of ``--quick`` runs.
QUICK_RATES = (np.array([0.3, 3.0]), np.array([0.05, 0.5]))
#: Columns of ``results.csv``.
RESULT_COLUMNS = ("variant", *SCORE_KEYS, *COUNT_KEYS)


class DemoResult(NamedTuple):
    """What the demo measured.

    Attributes:
        rows: UM and GM scores on the test span (:data:`RESULT_COLUMNS`).
        sweep: the magnitude sweep.
        files: the files written.
        seconds: wall time of each step, ``{step: seconds}``.
    """

    rows: list[dict[str, Any]]
    sweep: MagnitudeSweep
    files: list[Path]
    seconds: dict[str, float]


def run_demo(
    out_dir: str | Path = "jaxtrack-demo",
    seed: int = 0,
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
) -> DemoResult:
    """Runs the demo and writes its files into ``out_dir``.

    Args:
        out_dir: the output folder (created if needed).
        seed: seeds the scene, the learning and the tracking.
        quick: a seconds-long smoke run (short scene, few particles, 2 x 2 grid).
        progress: called with a short description before each step.

    Returns:
        The :class:`DemoResult`.

    Raises:
        InputError: a bad output folder or seed.
    """

    notify = progress or (lambda _: None)
    seconds: dict[str, float] = {}
    clock = time.perf_counter()

    def lap(step: str) -> None:
        nonlocal clock
        now = time.perf_counter()
        seconds[step] = round(now - clock, 1)
        clock = now

    out = output_folder(out_dir)
    notify(f"simulating the synthetic scene of seed {seed}")
    scene_dir = synthetic_sequence(out / "scene", seed, quick)
    split = split_halves(scene_dir)
    info = split.test.info
    config = QUICK_TRACKER_CONFIG if quick else PHDConfig()
    lap("simulate")

    notify(f"learning context on frames {split.train.first_frame}:{split.train.last_frame}")
    learned = learn_split(split, config, seed)
    context = Context.from_learned(learned)
    truth = load_context_truth(scene_dir / "context_truth.npz")
    files = save_context_plots(out, learned, info.im_width, info.im_height, truth)
    lap("learn context")

    notify(f"tracking frames {split.test.first_frame}:{split.test.last_frame} with UM and GM")
    params = variant_params(info, config, context)
    results = track_sequences([split.test, split.test], config, seed, params)
    rows = []
    for variant, result in zip(("UM", "GM"), results, strict=True):
        path = out / f"{variant}.txt"
        write_results(path, result.frames, result.ids, result.boxes, result.confs)
        files.append(path)
        rows.append({"variant": variant, **score_summary(evaluate_rows(split.test, result))})
    files.append(write_csv(out / "results.csv", rows, RESULT_COLUMNS))
    lap("track UM and GM")

    rates = QUICK_RATES if quick else (DEMO_CLUTTER_RATES, DEMO_BIRTH_RATES)
    notify(f"sweeping {len(rates[0])} x {len(rates[1])} magnitudes for UM and GM")
    sweep = magnitude_sweep(split, context, config, seed, *rates)
    files += write_sweep_files(sweep, out, info.name)
    lap("magnitude sweep")

    notify("drawing the figures")
    frame_index = split.test.num_frames // 2
    files.append(
        phd_frame_figure(
            phd_frame_snapshot(
                phd_filter_of(config),
                jax.random.PRNGKey(seed),
                params[1],
                split.test.detections,
                frame_index,
            ),
            out / "tracks.png",
            first_frame=split.test.first_frame,
            image_size=(info.im_width, info.im_height),
        )
    )
    files.append(save_demo_figure(out / "demo.png", context, sweep, rows, info))
    lap("figures")

    summary = out / "summary.md"
    summary.write_text(demo_markdown(rows, sweep, split, seed, quick, config, seconds))
    files.append(summary)
    return DemoResult(rows, sweep, files, seconds)


def demo_markdown(
    rows: list[dict[str, Any]],
    sweep: MagnitudeSweep,
    split,
    seed: int,
    quick: bool,
    config: PHDConfig,
    seconds: dict[str, float],
) -> str:
    """The demo's ``summary.md`` (also printed by ``jaxtrack demo``)."""
    head = sweep_summary(sweep)
    meta = sweep.context
    lines = [
        f"# jaxtrack demo: {split.test.info.name} (seed {seed}{', quick run' if quick else ''})\n",
        f"Context learned on frames {split.train.first_frame}:{split.train.last_frame}: "
        f"{meta['birth']['num_events']} births (lambda_s {meta['birth']['magnitude']:.3f}/frame, "
        f"{meta['birth']['components_alive']} Gaussians), {meta['clutter']['num_events']} "
        f"clutter detections (lambda_r {meta['clutter']['magnitude']:.3f}/frame, "
        f"{meta['clutter']['components_alive']} Gaussians). Frames "
        f"{split.test.first_frame}:{split.test.last_frame} tracked with "
        f"{config.num_particles} particles, configured magnitudes lambda_r "
        f"{config.clutter_rate}, lambda_s {config.birth_rate} (scores in %):\n",
        markdown_table(rows, RESULT_COLUMNS),
        f"Magnitude sweep ({len(sweep.clutter_rates)} x {len(sweep.birth_rates)} grid, one "
        f"vmapped call): best MOTA UM {head['best']['UM']['MOTA']:.1f}, GM "
        f"{head['best']['GM']['MOTA']:.1f}; GM better than UM at "
        f"{100 * head['gm_better_fraction']:.0f}% of the grid points.\n",
        "Time per step (s): " + ", ".join(f"{k} {v}" for k, v in seconds.items()) + f"; total "
        f"{sum(seconds.values()):.0f} s.\n",
    ]
    return "\n".join(lines)
