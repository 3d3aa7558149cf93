"""Association: gated assignment and track labelling of the PHD estimates."""

from jaxtrack.association.assignment import gated_assignment
from jaxtrack.association.estimates import Estimates
from jaxtrack.association.labelling import (
    LabelParams,
    Labels,
    LabelState,
    init_labels,
    label_step,
)
from jaxtrack.association.offline import finalise_tracks, track_rows

__all__ = [
    "Estimates",
    "LabelParams",
    "LabelState",
    "Labels",
    "finalise_tracks",
    "gated_assignment",
    "init_labels",
    "label_step",
    "track_rows",
]
