"""Shared PyTree types, and the one host-side row table.

Boxes are stored as MOTChallenge ``(x, y, w, h)``: top-left corner, width and height, in
pixels. Variable-size sets per frame are padded to a fixed capacity with a boolean mask so
that a whole sequence can go through ``jax.lax.scan`` with one compiled step. Padded slots
hold safe values (a unit box at the origin, score 0, id -1) so that logs and divisions stay
finite before masking.

Dimension names used in annotations: ``num_frames``, ``max_detections``, ``max_objects``,
``num_particles``, ``state_dim``, ``meas_dim``, ``num_components``, ``height``, ``width``.

:class:`MotTable` holds rows (one box each) host-side in NumPy: MOTChallenge files as read,
and tracker output (:func:`jaxtrack.association.offline.track_rows` /
:func:`~jaxtrack.association.offline.finalise_tracks`) as written.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from jaxtyping import Array, Bool, Float, Int, UInt8

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


class FrameInputs(NamedTuple):
    """What a filter that looks at the images gets per frame: detections and the frame.

    The inputs of such a filter's ``step(key, state, params, inputs_t)`` (DESIGN.md, "Frames
    under jit"); :func:`~jaxtrack.filters.base.run` stacks them over frames (a leading
    ``num_frames`` axis on every leaf) and, chunked, reads the frames chunk by chunk.

    Attributes:
        detections: the frame's padded :class:`Detections` (``[max_detections]`` leaves).
        frame: the image, RGB ``uint8`` ``[height, width, 3]`` (as
            :class:`~jaxtrack.io.video.VideoReader` reads it); zeros in a skipped padded frame.
    """

    detections: Detections
    frame: UInt8[Array, "height width 3"]


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


@dataclasses.dataclass(frozen=True)
class MotTable:
    """Rows of a MOTChallenge file (float64, exact, as read) or of a tracker's output, host-side.

    Attributes:
        frames: 1-based frame number of each row, ``[num_rows]``.
        ids: object id of each row (-1 for detections), ``[num_rows]``.
        boxes: ``(x, y, w, h)``, ``[num_rows, 4]``.
        confs: column 7 (detector or tracker score; in gt 0 means "ignore"), ``[num_rows]``.
        extra: columns 8.. as read (``-1`` for tracker output), ``[num_rows, num_columns - 7]``.
        lines: 1-based line number each row came from (0 for rows not read from a file).
        path: the file the rows came from, if any.
    """

    frames: np.ndarray
    ids: np.ndarray
    boxes: np.ndarray
    confs: np.ndarray
    extra: np.ndarray
    lines: np.ndarray
    path: str | None = None

    def __len__(self) -> int:
        return int(self.frames.shape[0])

    @classmethod
    def from_arrays(
        cls,
        frames,
        ids,
        boxes,
        confs=None,
        extra=None,
        path: str | None = None,
    ) -> MotTable:
        """Builds a table from arrays (e.g. a tracker's output); ``confs`` default to 1."""
        frames = np.asarray(frames, dtype=np.int64).reshape(-1)
        n = frames.shape[0]
        confs = np.ones(n) if confs is None else np.asarray(confs, dtype=np.float64).reshape(n)
        extra = np.full((n, 3), -1.0) if extra is None else np.asarray(extra, dtype=np.float64)
        if extra.ndim != 2 or extra.shape[0] != n:
            raise ValueError(f"extra must have shape (num_rows, k), got {extra.shape}")
        return cls(
            frames=frames,
            ids=np.asarray(ids, dtype=np.int64).reshape(n),
            boxes=np.asarray(boxes, dtype=np.float64).reshape(n, 4),
            confs=confs,
            extra=extra,
            lines=np.zeros(n, dtype=np.int64),
            path=path,
        )

    def select(self, keep: np.ndarray) -> MotTable:
        """Returns the rows where the boolean (or index) array ``keep`` selects."""
        return dataclasses.replace(
            self,
            frames=self.frames[keep],
            ids=self.ids[keep],
            boxes=self.boxes[keep],
            confs=self.confs[keep],
            extra=self.extra[keep],
            lines=self.lines[keep],
        )

    def frame_span(self, start: int, end: int) -> MotTable:
        """Rows with ``start <= frame <= end`` (1-based, inclusive)."""
        return self.select((self.frames >= start) & (self.frames <= end))

    @property
    def ignored(self) -> np.ndarray:
        """Ground-truth convention: rows with ``conf == 0`` are to be ignored."""
        return self.confs == 0
