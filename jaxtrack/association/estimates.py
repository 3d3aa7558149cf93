"""The per-frame multi-target estimates that state extraction hands to the labelling."""

from __future__ import annotations

from typing import NamedTuple

from jaxtyping import Array, Bool, Float


class Estimates(NamedTuple):
    """Extracted target states of one frame, padded to a fixed number of slots.

    Attributes:
        states: ``(y1, vy1, y2, vy2, w, h)`` per slot.
        masses: PHD mass of the cluster / detection part each estimate comes from.
        scores: score of the detection behind each estimate (for clusters, the
            mass-weighted mean over its particles of the expected score of the detections
            that updated them).
        mask: True where a slot holds an estimate.
    """

    states: Float[Array, "max_estimates 6"]
    masses: Float[Array, " max_estimates"]
    scores: Float[Array, " max_estimates"]
    mask: Bool[Array, " max_estimates"]
