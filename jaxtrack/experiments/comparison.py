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
:func:`~jaxtrack.experiments.common.common_shapes`). With several sequences, a pooled row
per tracker (:func:`~jaxtrack.metrics.evaluate.combine_sequences`) closes the table.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from jaxtrack.context.learn import learn_context
from jaxtrack.errors import InputError
from jaxtrack.experiments.common import (
    COUNT_KEYS,
    SCORE_KEYS,
    Split,
    common_shapes,
    evaluate_rows,
    score_summary,
)
from jaxtrack.filters.phd_tracker import (
    DEFAULT_CONFIG,
    Context,
    track_sequences,
    tracker_params,
)
from jaxtrack.metrics.evaluate import combine_sequences

#: The compared trackers: name -> (``track_sequences`` tracker, Kalman preset or variant).
TRACKERS = {
    "PHD-GM": ("phd", "GM"),
    "PHD-UM": ("phd", "UM"),
    "Kalman": ("kalman", "default"),
    "SORT-like": ("kalman", "sort"),
}
#: The columns of :func:`comparison_table`'s rows, in order.
COMPARISON_COLUMNS = ("sequence", "tracker", *SCORE_KEYS, *COUNT_KEYS, "context")


def comparison_table(
    splits: Sequence[Split],
    config: dict[str, Any] | None = None,
    seed: int = 0,
    combined_name: str | None = None,
    progress: bool = False,
) -> list[dict[str, Any]]:
    """Scores the :data:`TRACKERS` on the test half of every split.

    Args:
        splits: the sequences' training and test spans (with ground truth).
        config: overrides of :data:`~jaxtrack.filters.phd_tracker.DEFAULT_CONFIG` (its
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
    config = {**DEFAULT_CONFIG, **(config or {})}
    contexts, notes = _learn_contexts(splits, config, seed, progress)
    tests = [split.test for split in splits]
    uniform = [tracker_params(test.info, config) for test in tests]
    learned = [
        tracker_params(test.info, config, context, "GM") if context is not None else params
        for test, context, params in zip(tests, contexts, uniform, strict=True)
    ]
    params = common_shapes(learned + uniform)
    results = {
        "PHD-GM": track_sequences(tests, config, seed, params[: len(tests)], progress),
        "PHD-UM": track_sequences(tests, config, seed, params[len(tests) :], progress),
    }
    kalman_config = {key: config[key] for key in ("output", "max_gap")}
    for name, (tracker, preset) in TRACKERS.items():
        if tracker == "kalman":
            results[name] = track_sequences(
                tests, kalman_config, seed, tracker="kalman", preset=preset, progress=progress
            )
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
    splits: Sequence[Split], config: dict[str, Any], seed: int, progress: bool
) -> tuple[list[Context | None], list[str]]:
    """GM contexts of the training halves, None (with the reason) where none can be learned."""
    items = splits
    if progress:
        from tqdm import tqdm

        items = tqdm(splits, desc="learning context", unit="seq")
    contexts, notes = [], []
    for split in items:
        try:
            learned = learn_context(split.train, seed=seed, num_particles=config["num_particles"])
        except InputError as err:
            contexts.append(None)
            notes.append(f"uniform: {err}")
            continue
        contexts.append(Context(learned.birth, learned.clutter, learned.metadata))
        births, clutter = learned.metadata["birth"], learned.metadata["clutter"]
        notes.append(
            f"learned on frames {split.train.first_frame}:{split.train.last_frame} "
            f"({births['num_events']} births, {clutter['num_events']} clutter)"
        )
    return contexts, notes


def _row(sequence: str, tracker: str, scores: dict, context: str) -> dict[str, Any]:
    return {"sequence": sequence, "tracker": tracker, **scores, "context": context}
