"""Shared PyTree types.

Boxes are stored as MOTChallenge ``(x, y, w, h)``: top-left corner, width and height, in
pixels. Variable-size sets per frame are padded to a fixed capacity with a boolean mask so
that a whole sequence can go through ``jax.lax.scan`` with one compiled step. Padded slots
hold safe values (a unit box at the origin, score 0, id -1) so that logs and divisions stay
finite before masking.

Dimension names used in annotations: ``num_frames``, ``max_detections``, ``max_objects``,
``num_particles``, ``state_dim``, ``meas_dim``, ``num_components``.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

from jaxtyping import Array, Bool, Float, Int

#: Value written into padded box slots: a 1x1 box at the origin (positive size, finite logs).
PAD_BOX = (0.0, 0.0, 1.0, 1.0)


class Detections(NamedTuple):
    """Detections of a sequence, padded to ``max_detections`` per frame.

    Attributes:
        boxes: ``(x, y, w, h)`` of each detection; padded slots hold ``PAD_BOX``.
        scores: detector confidence; 0 in padded slots.
        mask: True where a slot holds a real detection.
    """

    boxes: Float[Array, "num_frames max_detections 4"]
    scores: Float[Array, "num_frames max_detections"]
    mask: Bool[Array, "num_frames max_detections"]


class GroundTruth(NamedTuple):
    """Ground-truth boxes of a sequence, padded to ``max_objects`` per frame.

    Attributes:
        boxes: ``(x, y, w, h)`` of each object; padded slots hold ``PAD_BOX``.
        ids: object identity; -1 in padded slots.
        mask: True where a slot holds a real ground-truth row (ignored ones included).
        ignored: True for rows flagged to be ignored (MOT ``conf`` column equal to 0);
            evaluation decides what to do with them.
    """

    boxes: Float[Array, "num_frames max_objects 4"]
    ids: Int[Array, "num_frames max_objects"]
    mask: Bool[Array, "num_frames max_objects"]
    ignored: Bool[Array, "num_frames max_objects"]


class Tracks(NamedTuple):
    """Labelled tracker output, padded to ``max_objects`` per frame.

    Attributes:
        boxes: ``(x, y, w, h)`` of each output box; padded slots hold ``PAD_BOX``.
        ids: persistent track identity; -1 in padded slots.
        scores: confidence (e.g. PHD mass of the cluster); 0 in padded slots.
        mask: True where a slot holds a real output box.
    """

    boxes: Float[Array, "num_frames max_objects 4"]
    ids: Int[Array, "num_frames max_objects"]
    scores: Float[Array, "num_frames max_objects"]
    mask: Bool[Array, "num_frames max_objects"]


@dataclasses.dataclass(frozen=True)
class SequenceInfo:
    """The ``[Sequence]`` section of ``seqinfo.ini``.

    Attributes:
        name: sequence name.
        seq_length: number of frames; frames are numbered ``1..seq_length``.
        im_width: image width in pixels.
        im_height: image height in pixels.
        frame_rate: frames per second, or None when not given.
    """

    name: str
    seq_length: int
    im_width: int
    im_height: int
    frame_rate: float | None = None
