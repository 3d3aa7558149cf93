"""Tracker comparison (PHD-context Fig. 16): the PHD tracker against data association.

On each sequence's :class:`~jaxtrack.experiments.common.Split` (learn on the first half,
score on the second) four trackers see the same detections:

* ``PHD-GM``: the PHD tracker with context learned on the training half (GM: births from a
  UM tracker run, clutter from the ground truth; PHD-context's proposed method). Where the
  training half yields no birth or clutter events, it falls back to uniform intensities
  and the row's ``context`` column says why.
* ``PHD-UM``: the PHD tracker with uniform intensities (the configured magnitudes).
* ``Kalman``: the data-association baseline (:mod:`jaxtrack.filters.kalman`, preset
  ``default``; no clutter model), standing in for the paper's DA tracker.
* ``SORT-like``: the same baseline with SORT's defaults (preset ``sort``).

Every tracker runs all sequences with one compile (PHD parameters padded to common shapes,
:func:`~jaxtrack.sweep.common_shapes`). With several sequences, a pooled row
per tracker (:func:`~jaxtrack.metrics.evaluate.combine_sequences`) closes the table.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from tqdm import tqdm

from jaxtrack.errors import InputError
from jaxtrack.experiments.common import (
    COUNT_KEYS,
    QUICK_TRACKER_CONFIG,
    SCORE_KEYS,
    Split,
    evaluate_rows,
    learn_split,
    markdown_table,
    output_folder,
    score_summary,
    split_halves,
    synthetic_sequence,
    write_csv,
)
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd_tracker import Context, PHDConfig, phd_params
from jaxtrack.metrics.evaluate import combine_sequences
from jaxtrack.pipelines.sweep import common_shapes
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.plot.experiments import save_comparison_figure

#: The compared trackers: name -> (``track_sequences`` tracker, Kalman preset or variant).
TRACKERS = {
    "PHD-GM": ("phd", "GM"),
    "PHD-UM": ("phd", "UM"),
    "Kalman": ("kalman", "default"),
    "SORT-like": ("kalman", "sort"),
}
#: What each tracker is, for summaries.
TRACKER_DESCRIPTIONS = {
    "PHD-GM": "PHD tracker, context (birth and clutter) learned on the training half",
    "PHD-UM": "PHD tracker, uniform birth and clutter intensities",
    "Kalman": "Kalman data-association baseline, preset `default` (no clutter model)",
    "SORT-like": "Kalman data-association baseline, preset `sort` (SORT's defaults)",
}
#: The columns of :func:`comparison_table`'s rows, in order.
COMPARISON_COLUMNS = ("sequence", "tracker", *SCORE_KEYS, *COUNT_KEYS, "context")


def comparison_table(
    splits: Sequence[Split],
    config: PHDConfig | None = None,
    seed: int = 0,
    combined_name: str | None = None,
    progress: bool = False,
) -> list[dict[str, Any]]:
    """Scores the :data:`TRACKERS` on the test half of every split.

    Args:
        splits: the sequences' training and test spans (with ground truth).
        config: the tracker configuration (default ``PHDConfig()``) (its
            ``num_particles`` also sets the particles of the UM run that yields birth
            events; the Kalman trackers use only its ``output`` and ``max_gap``).
        seed: seeds the learning and every tracker.
        combined_name: the ``sequence`` name of the pooled rows (one per tracker), added
            when given and there are several splits.
        progress: progress bars over the sequences.

    Returns:
        One dict per (sequence, tracker) with the :data:`COMPARISON_COLUMNS`, sequence by
        sequence in the order given, then the pooled rows.

    Raises:
        InputError: no splits or a bad configuration.
    """
    if not splits:
        raise InputError("no sequences to compare trackers on")
    config = config or PHDConfig()
    contexts, notes = _learn_contexts(splits, config, seed, progress)
    tests = [split.test for split in splits]
    uniform = [phd_params(config, test.info) for test in tests]
    learned = [
        phd_params(config, test.info, context, "GM") if context is not None else params
        for test, context, params in zip(tests, contexts, uniform, strict=True)
    ]
    params = common_shapes(learned + uniform)
    results = {
        "PHD-GM": track_sequences(tests, config, seed, params[: len(tests)], progress),
        "PHD-UM": track_sequences(tests, config, seed, params[len(tests) :], progress),
    }
    for name, (tracker, preset) in TRACKERS.items():
        if tracker == "kalman":
            kalman = KalmanConfig(preset=preset, output=config.output, max_gap=config.max_gap)
            results[name] = track_sequences(tests, kalman, seed, progress=progress)
    rows = []
    evaluations: dict[str, list] = {name: [] for name in TRACKERS}
    for index, test in enumerate(tests):
        for name in TRACKERS:
            evaluation = evaluate_rows(test, results[name][index])
            evaluations[name].append(evaluation)
            note = notes[index] if name == "PHD-GM" else ""
            rows.append(_row(test.info.name, name, score_summary(evaluation), note))
    if combined_name is not None and len(tests) > 1:
        for name in TRACKERS:
            scores = score_summary(combine_sequences(evaluations[name]))
            rows.append(_row(combined_name, name, scores, ""))
    return rows


def _learn_contexts(
    splits: Sequence[Split], config: PHDConfig, seed: int, progress: bool
) -> tuple[list[Context | None], list[str]]:
    """GM contexts of the training halves, None (with the reason) where none can be learned."""
    items = splits
    if progress:
        items = tqdm(splits, desc="learning context", unit="seq")
    contexts, notes = [], []
    for split in items:
        try:
            learned = learn_split(split, config, seed)
        except InputError as err:
            contexts.append(None)
            notes.append(f"uniform: {err}")
            continue
        contexts.append(Context.from_learned(learned))
        births, clutter = learned.metadata["birth"], learned.metadata["clutter"]
        notes.append(
            f"learned on frames {split.train.first_frame}:{split.train.last_frame} "
            f"({births['num_events']} births, {clutter['num_events']} clutter)"
        )
    return contexts, notes


def _row(sequence: str, tracker: str, scores: dict, context: str) -> dict[str, Any]:
    return {"sequence": sequence, "tracker": tracker, **scores, "context": context}


def run_comparison(
    out_dir: str | Path,
    seed: int = 0,
    quick: bool = False,
    sequence_dir: str | Path | None = None,
    mot_root: str | Path | None = None,
    progress: bool = True,
) -> tuple[list[dict[str, Any]], list[Path]]:
    """The whole Fig. 16 experiment: ``comparison.csv|png`` and ``summary.md`` in ``out_dir``.

    Args:
        out_dir: the output folder (created if needed).
        seed: seeds the synthetic scene, the learning and the trackers.
        quick: a seconds-long smoke run (short synthetic scene, few particles).
        sequence_dir: a MOTChallenge sequence folder with ground truth; default: the
            synthetic scene of ``seed``, written to ``out_dir/scene``.
        mot_root: a folder of sequence folders, each compared too (with a pooled row per
            tracker); None for none.
        progress: progress bars over the sequences.

    Returns:
        The table rows (those of :func:`comparison_table`, the synthetic or given sequence
        first, then the benchmark's) and the files written.

    Raises:
        InputError: bad data, a ``mot_root`` without sequence folders, or a bad output folder.
    """

    start = time.perf_counter()
    out = output_folder(out_dir)
    if sequence_dir is None:
        sequence_dir = synthetic_sequence(out / "scene", seed, quick)
    config = QUICK_TRACKER_CONFIG if quick else PHDConfig()
    rows = comparison_table([split_halves(sequence_dir)], config, seed, progress=progress)
    root_note = ""
    if mot_root is not None:
        root = Path(mot_root)
        folders = (
            sorted(p for p in root.iterdir() if (p / "seqinfo.ini").is_file())
            if (root.is_dir())
            else []
        )
        if not folders:
            raise InputError(f"{root}: no sequence folders (with seqinfo.ini) found")
        combined = f"{root.name} combined"
        splits = [split_halves(folder) for folder in folders]
        rows += comparison_table(splits, config, seed, combined, progress=progress)
        root_note = f" and on the {len(folders)} sequences of `{root}` (pooled: `{combined}`)"
    csv_path = write_csv(out / "comparison.csv", rows, COMPARISON_COLUMNS)
    png_path = save_comparison_figure(
        rows, out / "comparison.png", title="PHD-context vs data association (test halves)"
    )
    notes = sorted({f"- {row['sequence']}: {row['context']}" for row in rows if row["context"]})
    summary = [
        "# Tracker comparison (PHD-context Fig. 16)\n",
        f"On `{sequence_dir}`{root_note}: context learned on the first half of each sequence, "
        f"every tracker scored on the second half, same detections (seed {seed}"
        f"{', quick run' if quick else ''}; PHD with {config.num_particles} particles). "
        "Scores in %, CLEAR MOT MOTA/MOTP, VACE MODA/MODP (pooled), IDF1, HOTA.\n",
        markdown_table(rows, COMPARISON_COLUMNS[:-1]),
        "Trackers:\n",
        *(f"- {name}: {text}" for name, text in TRACKER_DESCRIPTIONS.items()),
        "\nContext of PHD-GM per sequence:\n",
        *notes,
        f"\nRun time {time.perf_counter() - start:.0f} s (compiles included). Files: "
        f"`{csv_path.name}`, `{png_path.name}`.\n",
    ]
    md_path = out / "summary.md"
    md_path.write_text("\n".join(summary))
    return rows, [csv_path, png_path, md_path]
