"""Detections that targets generate besides their own, learned on a training span.

A real detector gives some people a second box, a box on a part of the person, or one box
around two people (on PETS09-S2L1 1:397, 369 of the 508 detections the ground truth leaves
unmatched overlap a person by IoU >= 0.2). :mod:`jaxtrack.context.samples` leaves these out
of the clutter events, since they are not false alarms of the *scene*: counted as clutter
they would put the clutter density on the targets' paths. What generates them is the
targets, so their intensity moves with the targets:

    kappa_t(z) = rate * int q(z | x) D(x) dx,   q(z | x) = N(z; h(x), diag(s(x))^2),

with ``s(x) = noise_std * (w, h, w, h)`` the SDV scale of the target's box (the
likelihood's form, :func:`~jaxtrack.models.noise.state_dependent_std`). The PHD update adds
it to the scene's clutter ``kappa(z)`` (:class:`~jaxtrack.filters.phd.TargetClutter`,
:func:`~jaxtrack.filters.phd.phd_update`): a detection beside a tracked target is then
explained as that target's extra detection rather than as a new target (a duplicate box).

**Estimates** (maximum likelihood, the events' offsets from the object they overlap taken
as zero-mean Gaussian per dimension):

    rate = (n - n_c) / N,      noise_std_d = sqrt(mean_i (o_id)^2),

``n`` the extra detections (unmatched, overlapping an object box by IoU >=
:data:`~jaxtrack.context.samples.OBJECT_OVERLAP`), ``N`` the object boxes of the span, and
``o_i = ((cx_i - cx) / w, (cy_i - cy) / h, (w_i - w) / w, (h_i - h) / h)`` relative to the
best-overlapping object box ``(cx, cy, w, h)`` of its frame. ``n_c`` is the scene's clutter
that landed on an object by chance: the clutter magnitude already counts it back (it divides
the kept clutter events by the coverage ``1 - p``,
:func:`~jaxtrack.context.samples.chance_overlap`), so ``n_c = n_kept (1 / coverage - 1)``
is not the targets'. Nothing is learned (``rate = 0``: the paper's model, one detection per
target at most) unless the excess ``n - n_c`` is at least :data:`MIN_EVENTS` and
:data:`SIGNIFICANCE` standard deviations of a Poisson count of mean ``n_c``
(``n - n_c >= 3 sqrt(n_c)``): a detector that places its boxes well leaves only chance
overlaps, whose count scatters about ``n_c``. Each spread is at least
:data:`MIN_NOISE_STD` (a detector whose extra boxes all coincide would otherwise give a
singular ``q``).

Everything here is host-side NumPy; a context records the estimate in its metadata
(``target_clutter``), and :func:`~jaxtrack.filters.phd_tracker.phd_params` gives it to every
variant whose clutter is learned (GM, A2, A5, A6).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from jaxtrack.boxes import iou_matrix
from jaxtrack.types import MotTable

#: Fewest extra detections a spread is learned from.
MIN_EVENTS = 10
#: Standard deviations of the chance count (Poisson, mean ``n_c``) the extra detections must
#: exceed it by.
SIGNIFICANCE = 3.0
#: Smallest relative spread of ``q`` per dimension.
MIN_NOISE_STD = 0.02
#: Metadata key of a context's estimate.
METADATA_KEY = "target_clutter"


class TargetClutterFit(NamedTuple):
    """The estimate of a training span.

    Attributes:
        rate: extra detections per object box (per target per frame); 0 when not learned.
        noise_std: ``(s_1, s_2, s_w, s_h)`` relative spread (None when not learned).
        events: extra detections found.
        objects: object boxes of the span (the rate's denominator).
        source: ``"gt"`` or ``"tracks"`` (what the objects are).
        chance: the expected scene clutter among the events, ``n_c``.
    """

    rate: float
    noise_std: tuple[float, float, float, float] | None
    events: int
    objects: int
    source: str
    chance: float = 0.0

    @property
    def learned(self) -> bool:
        return self.rate > 0 and self.noise_std is not None

    def as_dict(self) -> dict[str, Any]:
        """The metadata record (JSON types)."""
        return {
            "rate": self.rate,
            "noise_std": None if self.noise_std is None else list(self.noise_std),
            "events": self.events,
            "objects": self.objects,
            "source": self.source,
            "chance": self.chance,
            "learned": self.learned,
        }


def extra_detection_offsets(
    det_table: MotTable, objects: MotTable, extra: np.ndarray
) -> np.ndarray:
    """Each extra detection's offset from the object box it overlaps most in its frame.

    Args:
        det_table: the detections.
        objects: the object boxes (gt rows or tracker output).
        extra: ``[len(det_table)]`` booleans, the extra detections (each overlaps an object
            of its frame).

    Returns:
        ``[n, 4]`` offsets ``((cx' - cx) / w, (cy' - cy) / h, (w' - w) / w, (h' - h) / h)``.
    """
    det_frames = np.asarray(det_table.frames)
    object_frames = np.asarray(objects.frames)
    det_boxes = np.asarray(det_table.boxes, np.float64)
    object_boxes = np.asarray(objects.boxes, np.float64)
    offsets = []
    for frame in np.unique(det_frames[extra]):
        rows = np.flatnonzero(extra & (det_frames == frame))
        candidates = object_boxes[object_frames == frame]
        if len(candidates) == 0:
            continue
        best = candidates[np.argmax(iou_matrix(det_boxes[rows], candidates), axis=1)]
        boxes = det_boxes[rows]
        offsets.append(
            np.stack(
                [
                    (boxes[:, 0] + boxes[:, 2] / 2 - best[:, 0] - best[:, 2] / 2) / best[:, 2],
                    (boxes[:, 1] + boxes[:, 3] / 2 - best[:, 1] - best[:, 3] / 2) / best[:, 3],
                    (boxes[:, 2] - best[:, 2]) / best[:, 2],
                    (boxes[:, 3] - best[:, 3]) / best[:, 3],
                ],
                axis=1,
            )
        )
    return np.concatenate(offsets) if offsets else np.zeros((0, 4))


def fit_target_clutter(
    offsets: np.ndarray, num_objects: int, source: str, chance: float = 0.0
) -> TargetClutterFit:
    """The maximum-likelihood rate and spread (module docstring) of a span's extra detections.

    Args:
        offsets: ``[n, 4]`` offsets (:func:`extra_detection_offsets`).
        num_objects: object boxes of the span.
        source: ``"gt"`` or ``"tracks"``.
        chance: ``n_c``, the scene clutter expected among them (>= 0).

    Returns:
        The :class:`TargetClutterFit` (rate 0 when the offsets beyond ``chance`` are fewer
        than :data:`MIN_EVENTS` or than :data:`SIGNIFICANCE` ``sqrt(chance)``, or without
        objects).
    """
    offsets = np.asarray(offsets, np.float64).reshape(-1, 4)
    count, chance = int(offsets.shape[0]), max(float(chance), 0.0)
    excess = count - chance
    if excess < max(MIN_EVENTS, SIGNIFICANCE * math.sqrt(chance)) or num_objects <= 0:
        return TargetClutterFit(0.0, None, count, int(num_objects), source, chance)
    spread = np.maximum(np.sqrt(np.mean(offsets**2, axis=0)), MIN_NOISE_STD)
    return TargetClutterFit(
        excess / num_objects,
        tuple(float(value) for value in spread),
        count,
        int(num_objects),
        source,
        chance,
    )


def learn_target_clutter(
    det_table: MotTable,
    objects: MotTable,
    extra: np.ndarray,
    num_objects: int,
    source: str,
    chance: float = 0.0,
) -> TargetClutterFit:
    """:func:`fit_target_clutter` of the extra detections ``extra`` of ``det_table``."""
    offsets = extra_detection_offsets(det_table, objects, extra)
    return fit_target_clutter(offsets, num_objects, source, chance)


def chance_events(kept: int, coverage: float) -> float:
    """``n_c = n_kept (1 / coverage - 1)``: the clutter events the clutter magnitude counts
    back as having landed on objects (:class:`~jaxtrack.context.samples.EventSamples`)."""
    return kept * (1.0 / coverage - 1.0)


def target_clutter_from_metadata(metadata: dict) -> tuple[float, tuple[float, ...]] | None:
    """``(rate, noise_std)`` a context's metadata records, or None (none learned)."""
    record = metadata.get(METADATA_KEY) or {}
    if not record.get("learned"):
        return None
    return float(record["rate"]), tuple(float(value) for value in record["noise_std"])


def invalid_target_clutter(record: object) -> str | None:
    """Why a context's ``target_clutter`` metadata cannot be used, or None when it can."""
    if not isinstance(record, dict):
        return f"{METADATA_KEY} must be a JSON object"
    if not record.get("learned"):
        return None
    rate, spread = record.get("rate"), record.get("noise_std")
    if not _is_number(rate) or not 0 < rate <= 100:
        return f"{METADATA_KEY} rate must be a number in (0, 100], got {rate!r}"
    if not isinstance(spread, list) or len(spread) != 4:
        return f"{METADATA_KEY} noise_std must be a list of 4 numbers, got {spread!r}"
    if not all(_is_number(value) and 0 < value <= 100 for value in spread):
        return f"{METADATA_KEY} noise_std values must lie in (0, 100], got {spread!r}"
    return None


def target_clutter_line(record: dict | None) -> str:
    """One line on a context's target clutter (``learn-context`` prints it)."""
    if not record:
        return "target clutter: none (an older context)"
    if not record.get("learned"):
        return (
            f"target clutter: not learned ({record['events']} detections beside objects, "
            f"{record.get('chance', 0.0):.1f} of them expected from the scene's clutter: no "
            "significant excess); one detection per target at most, as in the paper"
        )
    spread = ", ".join(f"{value:.2f}" for value in record["noise_std"])
    return (
        f"target clutter from {record['source']}: {record['events']} detections beside "
        f"{record['objects']} object boxes, {record.get('chance', 0.0):.1f} of them expected "
        f"from the scene's clutter ({record['rate']:.3f} per target per frame), "
        f"spread ({spread}) of the box (x, y, w, h); explains extra boxes on targets"
    )


def _is_number(value: object) -> bool:
    return (
        isinstance(value, int | float)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )
