"""Evaluate a tracker's output against ground truth: every metric, one sequence or many.

:func:`evaluate_sequence` scores one sequence and keeps each metric's additive fields, so
that :func:`combine_sequences` can pool several sequences with TrackEval's
``combine_sequences`` semantics (counts summed, ratios recomputed; HOTA's association and
localisation scores weighted by true positives; frame-averaged scores averaged over all
frames).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxtrack.errors import InputError
from jaxtrack.metrics import clear, cmt, hota, identity, ospa, switches, vace
from jaxtrack.metrics.preprocess import prepare_sequence

#: The scores ``jaxtrack eval --json`` prints, in this order.
SUMMARY_KEYS = (
    "MOTA",
    "MOTP",
    "MODA",
    "MODP",
    "IDF1",
    "IDP",
    "IDR",
    "HOTA",
    "DetA",
    "AssA",
    "LocA",
    "FP",
    "FN",
    "IDSW",
    "Frag",
    "MT",
    "PT",
    "ML",
    "GT_IDs",
    "Recall",
    "Precision",
    "VACE_MOTA",
    "VACE_MODA",
    "VACE_MODP",
    "OSPA",
    "GOSPA",
    "OE",
    "DE",
    "SE",
)


@dataclasses.dataclass(frozen=True)
class EvalConfig:
    """Evaluation settings.

    Attributes:
        iou_threshold: minimum IoU of a match for CLEAR MOT, identity and MODA/MODP
            (HOTA integrates over its own thresholds).
        centre_threshold: None to match boxes by IoU; otherwise match by centre distance,
            similarity ``max(0, 1 - d / (2 tau))`` with ``tau`` this value in pixels, so that
            boxes match when their centres are at most ``tau`` apart (``iou_threshold`` is
            then unused; MOTP, MODP and LocA become mean similarities).
        distractors: apply the MOT16/17 distractor rules (see
            :mod:`jaxtrack.metrics.preprocess`) instead of MOT15's.
        ospa_cutoff: OSPA/GOSPA cut-off ``c``.
        ospa_order: OSPA/GOSPA order ``p``.
        ospa_distance: ``"iou"`` (``1 - IoU``) or ``"centre"`` (pixels).
        vace_log_base: base of the identity-switch logarithm in VACE_MOTA.
        delay_tolerance: frames a tracker may take to pick up an entering target or release
            an exiting one without a delay error (CMT's DE, :mod:`jaxtrack.metrics.cmt`).
    """

    iou_threshold: float = 0.5
    centre_threshold: float | None = None
    distractors: bool = False
    ospa_cutoff: float = 1.0
    ospa_order: float = 1.0
    ospa_distance: str = "iou"
    vace_log_base: float = 10.0
    delay_tolerance: int = cmt.DEFAULT_TOLERANCE

    def __post_init__(self):
        if not (0.0 < self.iou_threshold <= 1.0):
            raise InputError(f"IoU threshold must be in (0, 1], got {self.iou_threshold}")
        if self.centre_threshold is not None and not (
            np.isfinite(self.centre_threshold) and self.centre_threshold > 0
        ):
            raise InputError(
                f"centre-distance threshold must be positive pixels, got {self.centre_threshold}"
            )
        if not (np.isfinite(self.vace_log_base) and self.vace_log_base > 1):
            raise InputError(f"VACE log base must be > 1, got {self.vace_log_base}")
        tolerance = self.delay_tolerance
        if (
            isinstance(tolerance, bool)
            or not isinstance(tolerance, int | np.integer)
            or tolerance < 0
        ):
            raise InputError(
                f"delay tolerance must be a whole number of frames >= 0, "
                f"got {self.delay_tolerance!r}"
            )
        try:
            ospa.check_parameters(self.ospa_cutoff, self.ospa_order, self.ospa_distance)
        except ValueError as err:
            raise InputError(str(err)) from None

    @property
    def match_threshold(self) -> float:
        """Similarity threshold of a match (0.5 under centre-distance matching)."""
        return 0.5 if self.centre_threshold is not None else self.iou_threshold


@dataclasses.dataclass(frozen=True)
class Evaluation:
    """Metric fields of one sequence, or of several combined.

    Attributes:
        clear: CLEAR MOT counts (:data:`jaxtrack.metrics.clear.ADDITIVE_FIELDS`).
        identity: ``IDTP, IDFN, IDFP``.
        hota: HOTA per-threshold arrays.
        vace: VACE sums (:data:`jaxtrack.metrics.vace.ADDITIVE_FIELDS`).
        set_distance: OSPA/GOSPA per-frame sums and ``num_frames``.
        cmt: CMT error counts (:data:`jaxtrack.metrics.cmt.ADDITIVE_FIELDS`).
        single_sequence: False for a combination of sequences.
        switches: the identity switches of each kind
            (:data:`jaxtrack.metrics.switches.KINDS`; they add up to ``IDSW``).
    """

    clear: dict
    identity: dict
    hota: dict
    vace: dict
    set_distance: dict
    cmt: dict
    single_sequence: bool = True
    switches: dict = dataclasses.field(default_factory=dict)

    def scores(self) -> dict:
        """Every score: the ``SUMMARY_KEYS`` first, then details (CLEAR/identity counts,
        HOTA sub-scores, OSPA/GOSPA components, CMT error counts, ``IDSW_<kind>`` switch
        counts)."""
        scores = {}
        scores.update(clear.clear_scores(self.clear, self.single_sequence))
        scores.update(identity.identity_scores(self.identity))
        scores.update(hota.hota_scores(self.hota))
        scores.update(vace.vace_scores(self.vace, self.single_sequence))
        scores.update(ospa.set_distance_scores(self.set_distance))
        scores.update(cmt.cmt_scores(self.cmt))
        ordered = {key: scores[key] for key in SUMMARY_KEYS}
        ordered.update({key: value for key, value in scores.items() if key not in ordered})
        ordered.update({key: int(self.identity[key]) for key in identity.ADDITIVE_FIELDS})
        ordered["TP"] = int(self.clear["TP"])
        ordered.update({switches.SCORE_NAMES[kind]: int(n) for kind, n in self.switches.items()})
        return ordered

    def summary(self) -> dict:
        """The ``SUMMARY_KEYS`` scores, as Python floats and ints."""
        scores = self.scores()
        return {key: scores[key] for key in SUMMARY_KEYS}


def evaluate_sequence(gt, result, frames: tuple[int, int] | None = None, config=None) -> Evaluation:
    """Scores a tracker's output on one sequence with every metric.

    Args:
        gt: ground truth (:class:`jaxtrack.types.MotTable`, all rows; conventions applied here).
        result: tracker output (:class:`jaxtrack.types.MotTable`).
        frames: ``(first, last)`` 1-based inclusive span scored (``(1, seqLength)`` for a
            whole sequence); default ``(1, last frame present in gt or result)``. Only the
            set distances depend on it (they average over its frames). Rows outside it are
            an error.
        config: :class:`EvalConfig` (default settings when None).

    Returns:
        The sequence's :class:`Evaluation`; ``.summary()`` gives the scores.

    Raises:
        InputError: rows outside ``frames`` or invalid settings.
        FileFormatError: a gt file the distractor rules cannot use.
    """
    config = config or EvalConfig()
    if frames is None:
        last = max(int(np.max(gt.frames, initial=1)), int(np.max(result.frames, initial=1)))
        frames = (1, last)
    data = prepare_sequence(gt, result, frames, config.centre_threshold, config.distractors)
    threshold = config.match_threshold
    matching = clear.clear_matching(data, threshold)
    mapped = vace.detection_mapping(data, threshold)
    return Evaluation(
        clear=clear.clear_fields(data, matching),
        identity=identity.identity_fields(data, threshold),
        hota=hota.hota_fields(data),
        vace=vace.vace_fields(data, mapped, matching, config.vace_log_base),
        set_distance=ospa.set_distance_fields(
            data, config.ospa_cutoff, config.ospa_order, config.ospa_distance
        ),
        cmt=cmt.cmt_fields(data, matching, config.delay_tolerance),
        switches=switches.classify_switches(data, matching).counts(),
    )


def combine_sequences(evaluations) -> Evaluation:
    """Pools sequences (TrackEval's ``combine_sequences`` for CLEAR, identity and HOTA).

    Args:
        evaluations: per-sequence :class:`Evaluation` objects (at least one).

    Returns:
        The combined :class:`Evaluation` (``single_sequence=False``).
    """
    evaluations = list(evaluations)
    if not evaluations:
        raise InputError("no sequences to combine")

    def summed(attribute: str) -> dict:
        fields = [getattr(evaluation, attribute) for evaluation in evaluations]
        return {key: sum(f[key] for f in fields) for key in fields[0]}

    return Evaluation(
        clear=summed("clear"),
        identity=summed("identity"),
        hota=hota.combine_hota([evaluation.hota for evaluation in evaluations]),
        vace=summed("vace"),
        set_distance=summed("set_distance"),
        cmt=summed("cmt"),
        single_sequence=False,
        switches=summed("switches"),
    )


def switch_table(gt, result, frames: tuple[int, int], config=None) -> switches.SwitchTable:
    """The classified switches of one sequence, with the matching of
    :func:`~jaxtrack.metrics.evaluate.evaluate_sequence` (same ``config``).

    Args:
        gt: ground truth (:class:`~jaxtrack.types.MotTable`, all rows as read).
        result: tracker output.
        frames: ``(first, last)`` 1-based inclusive span; every row must lie in it.
        config: :class:`EvalConfig` (default settings when None).

    Returns:
        The :class:`~jaxtrack.metrics.switches.SwitchTable`.
    """
    config = config or EvalConfig()
    data = prepare_sequence(gt, result, frames, config.centre_threshold, config.distractors)
    return switches.classify_switches(data, clear.clear_matching(data, config.match_threshold))
