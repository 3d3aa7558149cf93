"""Clutter labels: detections a person marked as "not an object of interest".

PHD-context Sec. IV learns the clutter intensity from clutter events. One source of them is
a person who looks at randomly chosen training frames and clicks the detections that are
clutter (``jaxtrack label-clutter``, :mod:`jaxtrack.plot.label_tool`). Every detection of a
labelled frame that was not clicked is an object, so the labels of a frame are complete once
the frame has been shown, and ``len(frames) / len(labelled_frames)`` estimates the mean
number of clutter events per frame.

The file is JSON (format version 1)::

    {
      "format_version": 1,
      "sequence": "PETS09-S2L1",
      "image_width": 768,
      "image_height": 576,
      "labelled_frames": [12, 57, 301],
      "pending_frames": [402, 650],
      "clutter": [{"frame": 57, "box": [612.0, 101.5, 27.0, 61.0]}]
    }

``labelled_frames`` are the frames shown to the user (ascending), ``pending_frames`` the
frames chosen for labelling but not shown yet (in showing order; a resumed session continues
with them), and each ``clutter`` entry is one detection of a labelled frame with its box
``x, y, w, h`` (top-left corner, pixels) exactly as in ``det/det.txt``: numbers are written
in the shortest form that reads back to the same float64.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

from jaxtrack.errors import FileFormatError, InputError, check_keys

#: Version written into (and required from) a labels file.
FORMAT_VERSION = 1


@dataclasses.dataclass(frozen=True)
class ClutterLabels:
    """Detections labelled as clutter on a set of frames of one sequence.

    Attributes:
        sequence: sequence name (``seqinfo.ini``'s ``name``).
        image_size: ``(width, height)`` in pixels.
        labelled_frames: 1-based frames whose labels are complete, ascending, unique,
            ``[num_labelled_frames]`` int64.
        frames: 1-based frame of each clutter detection, ``[num_clutter]`` int64; every one is
            in ``labelled_frames``.
        boxes: ``(x, y, w, h)`` of each clutter detection, ``[num_clutter, 4]`` float64.
        pending_frames: frames chosen for labelling but not shown yet, ``[num_pending]`` int64.
    """

    sequence: str
    image_size: tuple[int, int]
    labelled_frames: np.ndarray
    frames: np.ndarray
    boxes: np.ndarray
    pending_frames: np.ndarray = dataclasses.field(
        default_factory=lambda: np.zeros(0, dtype=np.int64)
    )

    def __post_init__(self) -> None:
        def setattr_(name, value):
            object.__setattr__(self, name, value)

        setattr_("image_size", (int(self.image_size[0]), int(self.image_size[1])))
        setattr_("labelled_frames", np.asarray(self.labelled_frames, np.int64).reshape(-1))
        setattr_("frames", np.asarray(self.frames, np.int64).reshape(-1))
        setattr_("boxes", np.asarray(self.boxes, np.float64).reshape(-1, 4))
        setattr_("pending_frames", np.asarray(self.pending_frames, np.int64).reshape(-1))
        _check(_to_json(self), "<ClutterLabels>", ValueError)

    def __len__(self) -> int:
        return int(self.frames.shape[0])

    @property
    def clutter_per_frame(self) -> float:
        """Mean number of labelled clutter detections per labelled frame (0 with none)."""
        num = self.labelled_frames.shape[0]
        return len(self) / num if num else 0.0


def save_clutter_labels(path: str | Path, labels: ClutterLabels) -> None:
    """Writes labels as JSON (see the module docstring), atomically.

    The file is written beside ``path`` under a temporary name and then renamed, so an
    interrupted save never leaves a half-written labels file.

    Args:
        path: the ``.json`` file to write; its folder is created if needed.
        labels: the labels.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = _to_json(labels)
    entries = [f"    {json.dumps(entry)}" for entry in data.pop("clutter")]
    lines = [f"  {json.dumps(key)}: {json.dumps(value)}," for key, value in data.items()]
    clutter = "[\n" + ",\n".join(entries) + "\n  ]" if entries else "[]"
    text = "{\n" + "\n".join(lines) + f'\n  "clutter": {clutter}\n}}\n'
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def load_clutter_labels(path: str | Path) -> ClutterLabels:
    """Reads and validates a labels file written by :func:`save_clutter_labels`.

    Args:
        path: the JSON file.

    Returns:
        The labels.

    Raises:
        FileFormatError: naming the file (and the line for JSON syntax errors, the JSON entry
            such as ``clutter[3].box`` for bad content): a missing or non-UTF-8 file, invalid
            JSON, a missing or unknown key, another ``format_version``, a non-positive image
            size or frame, a repeated frame, a clutter entry on a frame that is not labelled,
            a box that is not four finite numbers with positive width and height, or the same
            box twice on one frame.
    """
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(path, None, "labels file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as err:
        line = path.read_bytes()[: err.start].count(b"\n") + 1
        raise FileFormatError(path, line, "not UTF-8 text") from None
    try:
        data = json.loads(text, parse_constant=_reject_constant)
    except json.JSONDecodeError as err:
        raise FileFormatError(path, err.lineno, f"not valid JSON: {err.msg}") from None
    except ValueError as err:
        raise FileFormatError(path, None, str(err)) from None
    _check(data, path, None)
    return ClutterLabels(
        sequence=data["sequence"],
        image_size=(data["image_width"], data["image_height"]),
        labelled_frames=np.array(data["labelled_frames"], dtype=np.int64),
        frames=np.array([entry["frame"] for entry in data["clutter"]], dtype=np.int64),
        boxes=np.array([entry["box"] for entry in data["clutter"]], dtype=np.float64).reshape(
            -1, 4
        ),
        pending_frames=np.array(data["pending_frames"], dtype=np.int64),
    )


def choose_frames(first: int, last: int, num_frames: int, seed: int) -> np.ndarray:
    """Draws the frames to label: ``num_frames`` distinct frames of a span, uniformly.

    Frames without detections can be drawn too (they count as frames with no clutter), so
    that the labelled clutter rate per frame is unbiased.

    Args:
        first: first frame of the span (1-based).
        last: last frame of the span (inclusive).
        num_frames: how many to draw; the whole span when it is shorter.
        seed: seed of the draw (the same seed and span give the same frames).

    Returns:
        The frames, ascending, int64.

    Raises:
        InputError: an empty span, ``num_frames < 1`` or a negative seed.
    """
    if not 1 <= first <= last:
        raise InputError(f"frame span {first}:{last} must satisfy 1 <= start <= end")
    if num_frames < 1:
        raise InputError(f"number of frames to label must be >= 1, got {num_frames}")
    if seed < 0:
        raise InputError(f"seed must be >= 0, got {seed}")
    span = np.arange(first, last + 1, dtype=np.int64)
    rng = np.random.default_rng(seed)
    return np.sort(rng.choice(span, size=min(num_frames, span.shape[0]), replace=False))


def clutter_mask(labels: ClutterLabels, frames: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """Which detections are labelled clutter (exact match of frame and box).

    Args:
        labels: the labels.
        frames: 1-based frame of each detection, ``[num_detections]``.
        boxes: ``(x, y, w, h)`` of each detection, ``[num_detections, 4]``, as read from
            ``det.txt``.

    Returns:
        Boolean ``[num_detections]``: True where the detection is labelled clutter (identical
        detections, same frame and box, are all marked).

    Raises:
        InputError: a label matches no detection (the detections are not the ones that were
            labelled).
    """
    frames = np.asarray(frames, np.int64).reshape(-1)
    boxes = np.asarray(boxes, np.float64).reshape(-1, 4)
    rows: dict[tuple, list[int]] = {}
    for i, (frame, box) in enumerate(zip(frames, boxes, strict=True)):
        rows.setdefault((int(frame), tuple(box.tolist())), []).append(i)
    mask = np.zeros(frames.shape[0], dtype=bool)
    for i, (frame, box) in enumerate(zip(labels.frames, labels.boxes, strict=True)):
        matches = rows.get((int(frame), tuple(box.tolist())))
        if matches is None:
            raise InputError(
                f"clutter[{i}] (frame {int(frame)}, box {_numbers(box)}) matches no detection; "
                "were the labels made on these detections?"
            )
        mask[matches] = True
    return mask


def _to_json(labels: ClutterLabels) -> dict:
    return {
        "format_version": FORMAT_VERSION,
        "sequence": labels.sequence,
        "image_width": labels.image_size[0],
        "image_height": labels.image_size[1],
        "labelled_frames": labels.labelled_frames.tolist(),
        "pending_frames": labels.pending_frames.tolist(),
        "clutter": [
            {"frame": int(frame), "box": box.tolist()}
            for frame, box in zip(labels.frames, labels.boxes, strict=True)
        ],
    }


_KEYS = (
    "format_version",
    "sequence",
    "image_width",
    "image_height",
    "labelled_frames",
    "pending_frames",
    "clutter",
)


def _check(data, path, error: type[Exception] | None) -> None:
    """Validates parsed JSON; raises FileFormatError (or ``error``) naming the entry."""

    def fail(reason: str):
        if error is None:
            raise FileFormatError(path, None, reason)
        raise error(reason)

    def positive_int(value, where: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            fail(f"{where} must be a positive integer, got {json.dumps(value)}")
        return value

    def frame_list(key: str) -> list[int]:
        values = data[key]
        if not isinstance(values, list):
            fail(f"{key} must be a list of frame numbers")
        seen: set[int] = set()
        for i, value in enumerate(values):
            positive_int(value, f"{key}[{i}]")
            if value in seen:
                fail(f"{key}[{i}]: frame {value} appears twice")
            seen.add(value)
        return values

    if not isinstance(data, dict):
        fail("top level must be a JSON object")
    try:
        check_keys(data, _KEYS)
    except InputError as err:
        fail(str(err))
    if data["format_version"] != FORMAT_VERSION or isinstance(data["format_version"], bool):
        fail(f"format_version must be {FORMAT_VERSION}, got {json.dumps(data['format_version'])}")
    if not isinstance(data["sequence"], str) or not data["sequence"]:
        fail("sequence must be a non-empty string")
    positive_int(data["image_width"], "image_width")
    positive_int(data["image_height"], "image_height")
    labelled = frame_list("labelled_frames")
    if labelled != sorted(labelled):
        fail("labelled_frames must be in ascending order")
    pending = frame_list("pending_frames")
    both = sorted(set(labelled) & set(pending))
    if both:
        fail(f"frame {both[0]} is in both labelled_frames and pending_frames")
    clutter = data["clutter"]
    if not isinstance(clutter, list):
        fail("clutter must be a list of {'frame': F, 'box': [x, y, w, h]} objects")
    labelled_set = set(labelled)
    seen: dict[tuple, int] = {}
    for i, entry in enumerate(clutter):
        where = f"clutter[{i}]"
        if not isinstance(entry, dict) or set(entry) != {"frame", "box"}:
            fail(f"{where} must be an object with exactly the keys 'frame' and 'box'")
        frame = positive_int(entry["frame"], f"{where}.frame")
        if frame not in labelled_set:
            fail(f"{where}.frame {frame} is not in labelled_frames")
        box = entry["box"]
        if (
            not isinstance(box, list)
            or len(box) != 4
            or not all(_is_number(v) and math.isfinite(v) for v in box)
        ):
            fail(f"{where}.box must be 4 finite numbers [x, y, w, h], got {json.dumps(box)}")
        if box[2] <= 0 or box[3] <= 0:
            fail(f"{where}.box width and height must be positive, got {json.dumps(box)}")
        key = (frame, *(float(v) for v in box))
        if key in seen:
            fail(f"{where} repeats clutter[{seen[key]}] (frame {frame}, same box)")
        seen[key] = i


def _is_number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _reject_constant(name: str):
    raise ValueError(f"{name} is not allowed in a labels file")


def _numbers(values) -> str:
    return ",".join(np.format_float_positional(float(v), trim="-") for v in values)
