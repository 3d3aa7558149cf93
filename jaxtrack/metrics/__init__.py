"""Tracking metrics, TrackEval-exact: CLEAR MOT, VACE (MODA/MODP), identity, HOTA, OSPA/GOSPA;
and CMT's error rates OE, DE, SE (on the CLEAR matching, :mod:`jaxtrack.metrics.cmt`); the
kinds of the identity switches (:mod:`jaxtrack.metrics.switches`) and of the misses and false
positives, given the tracker's detections (:mod:`jaxtrack.metrics.errors`).

Start with :func:`evaluate_sequence` (one sequence, every metric) and
:func:`combine_sequences` (a benchmark's combined row); :func:`evaluate_tracks` scores padded
``Tracks`` (a batch of them, e.g. from a vmapped sweep); ``jaxtrack eval`` is the CLI.
"""

from jaxtrack.metrics.errors import ErrorTable, classify_errors
from jaxtrack.metrics.evaluate import (
    SUMMARY_KEYS,
    EvalConfig,
    Evaluation,
    combine_sequences,
    evaluate_sequence,
    switch_table,
)
from jaxtrack.metrics.ospa import set_distance_frames, set_distances
from jaxtrack.metrics.padded import evaluate_tracks, table_from_tracks
from jaxtrack.metrics.preprocess import SequenceData, prepare_sequence
from jaxtrack.metrics.switches import SwitchTable, classify_switches

__all__ = [
    "SUMMARY_KEYS",
    "ErrorTable",
    "EvalConfig",
    "Evaluation",
    "SequenceData",
    "SwitchTable",
    "classify_errors",
    "classify_switches",
    "combine_sequences",
    "evaluate_sequence",
    "evaluate_tracks",
    "prepare_sequence",
    "set_distance_frames",
    "set_distances",
    "switch_table",
    "table_from_tracks",
]
