"""What the Fusion tracker learns from a training span of the tracked sequence.

:func:`learn_fusion_context` takes the training span (``--train-frames A:B``, default the
first :attr:`~jaxtrack.filters.fusion_tracker.FusionConfig.train_fraction` of the tracked
span) and learns, as the paper's Sec. 2.3 and 3 describe:

* the **trajectories** of the span: its ground truth when the sequence folder has one
  (``gt/gt.txt``; rows with ``conf == 0`` left out), else the tracks of the PHD tracker with
  uniform intensities on the span's detections;
* the **entry/exit zones and activity mask** of those trajectories
  (:func:`~jaxtrack.context.zones.learn_zones`; when no trajectory starts or ends inside the
  span: no zones and the activity mask alone);
* the **local motion models** (:func:`~jaxtrack.context.motion_models.fit_motion_models` on
  their tracklets);
* the **voting thresholds** per region, calibrated on the detections the tracker runs on
  against the ground truth (:func:`~jaxtrack.filters.fusion_voting.region_thresholds`; a
  detection gap is a stretch of a target without a detection at IoU >= the tracker's
  support gate, :data:`~jaxtrack.filters.fusion_tracker.GATE`);
  without ground truth, or when the span has no false-positive run or no detection gap, the
  paper's thresholds for PETS 2009.

Scores on the training span are not held out: the experiment reports the span after it
separately.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxtrack.context.activity import ACTIVITY_CELL, activity_mask
from jaxtrack.context.motion_models import cut_tracklets, fit_motion_models
from jaxtrack.context.zones import SceneZones, learn_zones
from jaxtrack.detect.sequence import video_sequence
from jaxtrack.errors import InputError
from jaxtrack.filters.fusion_tracker import (
    GATE,
    PAPER_TH_INIT,
    PAPER_TH_TERM,
    FusionConfig,
    FusionContext,
)
from jaxtrack.filters.fusion_voting import (
    Thresholds,
    detection_gaps,
    false_positive_runs,
    initiation_runs,
    region_thresholds,
)
from jaxtrack.io import MotSequence, parse_frame_span, read_mot_file
from jaxtrack.pipelines.context import uniform_tracker_rows
from jaxtrack.types import MotTable


def training_frames(config: FusionConfig, seq: MotSequence, frames=None) -> tuple[int, int]:
    """The training span: ``frames`` (``"A:B"`` or a pair, inside the tracked span), else
    the first ``config.train_fraction`` of the tracked span (at least one frame).

    Raises:
        InputError: a malformed span or one outside the tracked span.
    """
    first, last = seq.first_frame, seq.last_frame
    if frames is None:
        count = max(round(config.train_fraction * seq.num_frames), 1)
        return first, first + count - 1
    start, end = parse_frame_span(frames, seq.info.seq_length)
    if not first <= start <= end <= last:
        raise InputError(
            f"training frames {start}:{end} must lie inside the tracked frames {first}:{last}"
        )
    return start, end


def sequence_ground_truth(seq: MotSequence) -> MotTable | None:
    """The ground truth of a loaded sequence: its own, else its folder's ``gt/gt.txt`` (a
    sequence whose detections came from elsewhere), else None."""
    if seq.gt_table is not None:
        return seq.gt_table
    path = Path(seq.path) / "gt" / "gt.txt"
    if not path.is_file():
        return None
    return read_mot_file(path, "gt", info=seq.info)


def learn_fusion_context(
    config: FusionConfig, seq: MotSequence, frames=None, seed: int = 0
) -> FusionContext:
    """The Fusion tracker's context learned on a training span of ``seq`` (module doc).

    Args:
        config: the tracker's configuration (training share, calibration share).
        seq: the tracked sequence (or span) with the detections the tracker runs on.
        frames: the training span (``"A:B"``), inside the tracked span; default
            :func:`training_frames`.
        seed: PRNG seed of the PHD run giving the trajectories when there is no ground truth.

    Raises:
        InputError: a bad training span; FileFormatError: a malformed ``gt/gt.txt``.
    """
    span = training_frames(config, seq, frames)
    info = seq.info
    detections = seq.det_table.frame_span(*span)
    gt = sequence_ground_truth(seq)
    notes = [f"trained on frames {span[0]}:{span[1]}"]
    if gt is not None:
        gt = gt.frame_span(*span)
        trajectories = gt.select(~gt.ignored)
        notes.append("ground-truth trajectories")
    else:
        trained = video_sequence(seq.path, detections, span, info)
        trajectories = uniform_tracker_rows(trained, seed)
        notes.append("PHD tracks as trajectories (no ground truth)")
    scene = _scene(trajectories, span, info.im_width, info.im_height, notes)
    motion = fit_motion_models(cut_tracklets(trajectories), info.im_width, info.im_height)
    thresholds = _thresholds(detections, gt, scene, config, notes)
    return FusionContext(scene, motion, thresholds, "; ".join(notes))


def _scene(trajectories: MotTable, span, width, height, notes: list[str]) -> SceneZones:
    """Zones and activity mask, or the mask alone when no zone can be learned."""
    try:
        scene = learn_zones(
            trajectories.frames, trajectories.ids, trajectories.boxes, span, width, height
        ).scene
        notes.append(f"{len(scene.boxes)} entry/exit zone(s)")
        return scene
    except InputError as err:
        notes.append(f"no zones ({err})")
    mask = activity_mask(trajectories.frames, trajectories.ids, trajectories.boxes, width, height)
    if not mask.any():
        mask = np.ones_like(mask)
    return SceneZones(np.zeros((0, 4), np.float32), mask, ACTIVITY_CELL)


def _thresholds(detections, gt, scene, config: FusionConfig, notes: list[str]) -> Thresholds:
    """Calibrated thresholds per region, or the paper's."""
    paper = Thresholds(np.full(3, PAPER_TH_INIT, np.int64), np.full(3, PAPER_TH_TERM, np.int64))
    if gt is None:
        notes.append(f"the paper's thresholds (th_init {PAPER_TH_INIT}, th_term {PAPER_TH_TERM})")
        return paper
    try:
        runs = false_positive_runs(detections, gt)
        gaps = detection_gaps(detections, gt, match_iou=GATE)
        starts = initiation_runs(detections, gt, GATE) if config.init_rule == "cost" else None
        found = region_thresholds(runs, gaps, scene, config.share, starts)
    except InputError as err:
        notes.append(f"the paper's thresholds ({err})")
        return paper
    starting = "" if starts is None else f", {len(starts.lengths)} target starts (cost rule)"
    notes.append(
        f"th_init {found.init.tolist()}, th_term {found.term.tolist()} (active, inactive, zone) "
        f"from {len(runs.lengths)} false-positive runs and {len(gaps.lengths)} detection gaps"
        f"{starting}"
    )
    return found
