"""Reading and writing MOTChallenge sequence folders and text files.

A MOTChallenge file has one object per line, comma-separated:
``frame, id, x, y, w, h, conf, c8, c9, c10``. Columns 8-10 are world coordinates in MOT15
(usually -1) and ``class, visibility`` in MOT16/17 ground truth (9 columns). In ground truth,
``conf == 0`` marks a row to be ignored by evaluation; this module keeps such rows and flags
them, the evaluation decides.

Host-side tables (:class:`~jaxtrack.types.MotTable`, NumPy, float64 exactly as read) feed
evaluation and file writing; :func:`pad_detections` / :func:`pad_ground_truth` turn them
into the fixed-capacity PyTrees of :mod:`jaxtrack.types` that a ``lax.scan`` consumes.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence as SequenceABC
from pathlib import Path

import numpy as np

from jaxtrack.errors import FileFormatError, InputError, InputWarning
from jaxtrack.limits import (
    FRAME_COUNT,
    FRAME_RATE,
    IMAGE_FACTOR,
    IMAGE_SIZE,
    MAX_ASPECT_RATIO,
    MAX_COORDINATE,
    MAX_FRAMES,
    MAX_ID,
    MAX_SCORE,
    MIN_BOX_SIZE,
    Rule,
    float32_trouble,
)
from jaxtrack.resources import check_memory, check_rows_per_frame, padded_sequence_bytes
from jaxtrack.types import PAD_BOX, Detections, GroundTruth, MotTable, SequenceInfo

MIN_COLUMNS = 7
MAX_COLUMNS = 10


@dataclasses.dataclass(frozen=True)
class MotSequence:
    """A loaded MOTChallenge sequence (or a frame span of it).

    Attributes:
        path: the sequence folder.
        info: parsed ``seqinfo.ini``.
        first_frame: 1-based number of the first frame in the span.
        last_frame: 1-based number of the last frame in the span (inclusive).
        det_table: detections of the span, host-side.
        gt_table: ground truth of the span, or None when the folder has no ``gt/gt.txt``.
        detections: padded detections, ``[num_frames, max_detections]``; index ``t`` is frame
            ``first_frame + t``.
        ground_truth: padded ground truth, or None.
    """

    path: Path
    info: SequenceInfo
    first_frame: int
    last_frame: int
    det_table: MotTable
    gt_table: MotTable | None
    detections: Detections
    ground_truth: GroundTruth | None

    @property
    def num_frames(self) -> int:
        return self.last_frame - self.first_frame + 1


def read_seqinfo(path: str | Path) -> SequenceInfo:
    """Parses a ``seqinfo.ini`` file.

    Rules (:mod:`jaxtrack.limits`): ``seqLength`` an integer in ``[1, MAX_FRAMES]``
    (10^6), ``imWidth`` and ``imHeight`` integers in ``[16, 65536]``, ``frameRate`` (optional)
    a number in ``[1, 1000]``; the first bad line is reported. An image more than
    :data:`~jaxtrack.limits.MAX_ASPECT_RATIO` (10) times wider than high, or higher than wide,
    gives an :class:`~jaxtrack.errors.InputWarning`.

    Args:
        path: path of the file.

    Returns:
        The sequence information.

    Raises:
        FileFormatError: naming the file (and the line), when the file is missing, has no
            ``[Sequence]`` section, a malformed line, a missing ``seqLength``, ``imWidth`` or
            ``imHeight``, or a value breaking its rule.
    """
    path = Path(path)
    text = _read_text(path)
    section = None
    values: dict[str, tuple[str, int]] = {}
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith((";", "#")):
            continue
        if line.startswith("["):
            if not line.endswith("]"):
                raise FileFormatError(path, number, f"malformed section header {line!r}")
            section = line[1:-1].strip()
            continue
        if "=" not in line:
            raise FileFormatError(path, number, f"expected 'key=value', got {line!r}")
        if section != "Sequence":
            continue
        key, value = (part.strip() for part in line.split("=", 1))
        values[key] = (value, number)
    if section is None and not values:
        raise FileFormatError(path, None, "no [Sequence] section")

    def checked(key: str, rule: Rule, parse):
        value, number = values[key]
        try:
            parsed = parse(value)
        except ValueError:
            kind = "an integer" if rule.kind is int else "a number"
            raise FileFormatError(
                path, number, f"{key} must be {kind} in {rule.interval()}, got {value[:40]!r}"
            ) from None
        try:
            return rule.check(key, parsed)
        except InputError as err:
            raise FileFormatError(path, number, str(err)) from None

    for key in ("seqLength", "imWidth", "imHeight"):
        if key not in values:
            raise FileFormatError(path, None, f"missing key {key!r} in [Sequence]")
    rules = {
        "seqLength": (FRAME_COUNT, int),
        "imWidth": (IMAGE_SIZE, int),
        "imHeight": (IMAGE_SIZE, int),
        "frameRate": (FRAME_RATE, float),
    }
    present = sorted((key for key in rules if key in values), key=lambda key: values[key][1])
    parsed = {key: checked(key, *rules[key]) for key in present}  # the first bad line first
    width, height = parsed["imWidth"], parsed["imHeight"]
    if max(width, height) > MAX_ASPECT_RATIO * min(width, height):
        warnings.warn(
            InputWarning(
                f"{path}: a {width}x{height} image is more than {MAX_ASPECT_RATIO} times wider "
                "than high (or higher than wide); are imWidth and imHeight right?"
            ),
            stacklevel=2,
        )
    name = values["name"][0] if "name" in values else path.parent.name
    return SequenceInfo(name, parsed["seqLength"], width, height, parsed.get("frameRate"))


def write_seqinfo(path: str | Path, info: SequenceInfo) -> None:
    """Writes ``seqinfo.ini`` in the MOTChallenge layout."""
    lines = ["[Sequence]", f"name={info.name}", "imDir=img1"]
    if info.frame_rate is not None:
        lines.append(f"frameRate={_format_number(info.frame_rate)}")
    lines += [
        f"seqLength={info.seq_length}",
        f"imWidth={info.im_width}",
        f"imHeight={info.im_height}",
        "imExt=.jpg",
    ]
    Path(path).write_text("\n".join(lines) + "\n")


def read_mot_file(
    path: str | Path,
    kind: str = "det",
    seq_length: int | None = None,
    info: SequenceInfo | None = None,
) -> MotTable:
    """Reads a MOTChallenge text file, validating every row.

    The rules (one per column, :mod:`jaxtrack.limits`; absolute ones always, image-relative
    ones when ``info`` gives the image size):

    * frame: an integer in ``[1, MAX_FRAMES]`` (10^6), and in ``[1, seq_length]`` when known;
    * id: an integer; det: in ``[-1, 2^31 - 1]``; gt and res: in ``[0, 2^31 - 1]`` (-1 marks
      padded slots), not repeated within a frame;
    * every real column (x, y, w, h, conf, extra): finite, ``|v| <= 3.4e38`` and 0 or
      ``|v| >= 1.2e-38`` (representable in float32, to which boxes and scores are cast);
    * ``|x|, |y| <= 2^20``; det and gt: ``w, h`` in ``[1, 2^20]`` pixels; res: ``w, h`` in
      ``(0, 2^20]``; ``|conf| <= 1e6``;
    * with an image of ``W x H``: ``w <= 10 W``, ``h <= 10 H``, ``x`` in ``[-10 W, 11 W]``,
      ``y`` in ``[-10 H, 11 H]``.

    Warnings (:class:`~jaxtrack.errors.InputWarning`): every box lies outside the image; a
    det file with scores outside ``[0, 1]``.

    Args:
        path: ``det.txt``, ``gt.txt`` or a tracker result file.
        kind: ``"det"``, ``"gt"`` or ``"res"``.
        seq_length: when given, every frame number must lie in ``1..seq_length``.
        info: the sequence (or video) information: its ``seq_length`` (unless
            ``seq_length`` is given) and image size apply.

    Returns:
        The rows as a :class:`MotTable`, in file order.

    Raises:
        FileFormatError: naming the file and line, for a missing file, a row with fewer than 7
            or more than 10 columns (or a different count than the first row), a non-numeric
            field, or a value breaking its rule.
    """
    if kind not in ("det", "gt", "res"):
        raise ValueError(f"kind must be 'det', 'gt' or 'res', got {kind!r}")
    if seq_length is None and info is not None:
        seq_length = info.seq_length
    path = Path(path)
    text = _read_text(path)
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    num_columns = None
    first_line = 0
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        fields = [f.strip() for f in line.split(",")] if "," in line else line.split()
        if not MIN_COLUMNS <= len(fields) <= MAX_COLUMNS:
            raise FileFormatError(
                path,
                number,
                f"expected {MIN_COLUMNS} to {MAX_COLUMNS} comma-separated columns "
                f"(frame,id,x,y,w,h,conf[,...]), got {len(fields)}",
            )
        if num_columns is None:
            num_columns, first_line = len(fields), number
        elif len(fields) != num_columns:
            raise FileFormatError(
                path,
                number,
                f"got {len(fields)} columns but line {first_line} has {num_columns}",
            )
        try:
            values = [float(f) for f in fields]
        except ValueError:
            bad = next(f for f in fields if not _is_float(f))
            column = fields.index(bad) + 1
            raise FileFormatError(
                path, number, f"column {column} is not a number: {bad[:40]!r}"
            ) from None
        rows.append(values)
        line_numbers.append(number)

    data = np.array(rows, dtype=np.float64).reshape(len(rows), num_columns or MAX_COLUMNS)
    lines = np.array(line_numbers, dtype=np.int64)
    _validate_rows(path, data, lines, kind, seq_length)
    what = {"det": "detections", "gt": "objects"}.get(kind, "rows")
    check_rows_per_frame(data[:, 0], path, what, lines=lines)
    if info is not None:
        _validate_image(path, data, lines, info)
    if kind == "det" and np.any((data[:, 6] < 0) | (data[:, 6] > 1)):
        i = int(np.argmax((data[:, 6] < 0) | (data[:, 6] > 1)))
        warnings.warn(
            InputWarning(
                f"{path}, line {lines[i]}: detection score {data[i, 6]:g} outside [0, 1] "
                "(the trackers' score thresholds assume probabilities)"
            ),
            stacklevel=2,
        )
    return MotTable(
        frames=data[:, 0].astype(np.int64),
        ids=data[:, 1].astype(np.int64),
        boxes=data[:, 2:6].copy(),
        confs=data[:, 6].copy(),
        extra=data[:, 7:].copy(),
        lines=lines,
        path=str(path),
    )


_COLUMN_NAMES = ("frame", "id", "x", "y", "w", "h", "conf")


def _fail(path, data, lines, bad: np.ndarray, reason) -> None:
    """Raises for the first row (in file order) where ``bad`` holds; ``reason(i)`` says why."""
    if np.any(bad):
        i = int(np.argmax(bad))
        raise FileFormatError(path, int(lines[i]), reason(i))


def _validate_rows(path, data, lines, kind, seq_length) -> None:
    """The absolute rules of :func:`read_mot_file` (see there)."""

    def fail(bad, reason):
        _fail(path, data, lines, bad, reason)

    fail(~np.isfinite(data).all(axis=1), lambda i: f"NaN or inf value in {_row_text(data[i])}")
    frames, ids = data[:, 0], data[:, 1]
    last = MAX_FRAMES if seq_length is None else min(seq_length, MAX_FRAMES)
    limit = (
        "seqLength"
        if seq_length is not None and seq_length <= MAX_FRAMES
        else f"at most {MAX_FRAMES:,} frames"
    )
    fail(frames != np.round(frames), lambda i: f"frame must be an integer, got {frames[i]:g}")
    fail(
        (frames < 1) | (frames > last),
        lambda i: f"frame {frames[i]:g} outside 1..{last} ({limit})",
    )
    fail(ids != np.round(ids), lambda i: f"id must be an integer, got {ids[i]:g}")
    lowest_id = -1 if kind == "det" else 0
    fail(
        (ids < lowest_id) | (ids > MAX_ID),
        lambda i: f"{kind} id must lie in [{lowest_id}, {MAX_ID}] (int32), got {ids[i]:g}",
    )
    trouble = float32_trouble(data[:, 2:])
    fail(
        trouble.any(axis=1),
        lambda i: (
            f"{_column_name(2 + int(np.argmax(trouble[i])))} = "
            f"{data[i, 2 + int(np.argmax(trouble[i]))]:g} is not representable in float32 "
            "(|v| <= 3.4e38 and 0 or |v| >= 1.2e-38)"
        ),
    )
    for column in (4, 5):
        name = _COLUMN_NAMES[column]
        if kind == "res":
            fail(
                data[:, column] <= 0,
                lambda i, c=column, n=name: f"{n} must be positive, got {data[i, c]:g}",
            )
        else:
            fail(
                data[:, column] < MIN_BOX_SIZE,
                lambda i, c=column, n=name: (
                    f"{n} {data[i, c]:g} is below {MIN_BOX_SIZE:g} pixel "
                    "(boxes are in pixels, not normalised)"
                ),
            )
    for column in (2, 3, 4, 5):
        fail(
            np.abs(data[:, column]) > MAX_COORDINATE,
            lambda i, c=column: (
                f"{_COLUMN_NAMES[c]} {data[i, c]:g} is beyond 2^20 = {MAX_COORDINATE:.0f} pixels"
            ),
        )
    fail(
        np.abs(data[:, 6]) > MAX_SCORE,
        lambda i: f"conf {data[i, 6]:g} outside [-{MAX_SCORE:g}, {MAX_SCORE:g}]",
    )
    if kind in ("gt", "res") and data.shape[0]:
        keys = data[:, 0].astype(np.int64) * (2**32) + (data[:, 1].astype(np.int64) % (2**32))
        order = np.argsort(keys, kind="stable")
        repeated = np.zeros(data.shape[0], dtype=bool)
        repeated[order[1:]] = keys[order[1:]] == keys[order[:-1]]
        if np.any(repeated):
            i = int(np.argmin(np.where(repeated, lines, np.iinfo(np.int64).max)))
            first = lines[order[np.searchsorted(keys[order], keys[i])]]
            raise FileFormatError(
                path,
                int(lines[i]),
                f"id {int(data[i, 1])} appears twice in frame {int(data[i, 0])} "
                f"(also on line {int(first)})",
            )


def _validate_image(path, data, lines, info: SequenceInfo) -> None:
    """The image-relative rules of :func:`read_mot_file`, and the all-outside warning."""
    x, y, w, h = data[:, 2], data[:, 3], data[:, 4], data[:, 5]
    width, height, factor = info.im_width, info.im_height, IMAGE_FACTOR
    image = f"the {width}x{height} image"

    def fail(bad, reason):
        _fail(path, data, lines, bad, reason)

    fail(w > factor * width, lambda i: f"w {w[i]:g} exceeds {factor} times {image}")
    fail(h > factor * height, lambda i: f"h {h[i]:g} exceeds {factor} times {image}")
    fail(
        (x < -factor * width) | (x > (factor + 1) * width),
        lambda i: f"x {x[i]:g} lies more than {factor} image widths outside {image}",
    )
    fail(
        (y < -factor * height) | (y > (factor + 1) * height),
        lambda i: f"y {y[i]:g} lies more than {factor} image heights outside {image}",
    )
    outside = (x >= width) | (y >= height) | (x + w <= 0) | (y + h <= 0)
    if data.shape[0] and np.all(outside):
        warnings.warn(
            InputWarning(
                f"{path}: all {data.shape[0]} boxes lie outside {image} (seqinfo.ini or video "
                "size); wrong image size or coordinates?"
            ),
            stacklevel=3,
        )


def write_mot_file(path: str | Path, table: MotTable) -> None:
    """Writes a table as a MOTChallenge file, one row per line, exactly round-trippable.

    Numbers are written in the shortest form that reads back to the same float64, so
    ``read_mot_file(write_mot_file(t))`` reproduces ``t``'s values exactly. Tables without
    extra columns are written with ``-1,-1,-1`` (the 10-column tracker result format that
    TrackEval reads).
    """
    extra = table.extra if table.extra.shape[1] else np.full((len(table), 3), -1.0)
    out = []
    for i in range(len(table)):
        numbers = [*table.boxes[i], table.confs[i], *extra[i]]
        out.append(
            f"{table.frames[i]},{table.ids[i]}," + ",".join(_format_number(v) for v in numbers)
        )
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text("".join(line + "\n" for line in out))


def write_results(path: str | Path, frames, ids, boxes, scores=None) -> None:
    """Writes tracker output as ``frame,id,x,y,w,h,conf,-1,-1,-1`` (sorted by frame, id)."""
    table = MotTable.from_arrays(frames, ids, boxes, scores)
    order = np.lexsort((table.ids, table.frames))
    write_mot_file(path, table.select(order))


def pad_detections(
    table: MotTable,
    first_frame: int,
    num_frames: int,
    capacity: int | None = None,
) -> Detections:
    """Pads a detection table into a fixed-capacity :class:`Detections` PyTree.

    Args:
        table: detections; rows outside the frame span are an error.
        first_frame: frame number of index 0.
        num_frames: number of frames.
        capacity: detections per frame; default: the largest count in the span (at least 1).

    Raises:
        InputError: a frame holds more detections than ``capacity`` (never a silent drop).
    """
    slot, capacity = _slots(table, first_frame, num_frames, capacity, "max_detections")
    t = table.frames - first_frame
    boxes = np.tile(np.asarray(PAD_BOX, np.float32), (num_frames, capacity, 1))
    scores = np.zeros((num_frames, capacity), np.float32)
    mask = np.zeros((num_frames, capacity), bool)
    boxes[t, slot] = table.boxes
    scores[t, slot] = table.confs
    mask[t, slot] = True
    return Detections(boxes=boxes, scores=scores, mask=mask)


def pad_ground_truth(
    table: MotTable,
    first_frame: int,
    num_frames: int,
    capacity: int | None = None,
) -> GroundTruth:
    """Pads a ground-truth table into a :class:`GroundTruth` PyTree (see pad_detections)."""
    slot, capacity = _slots(table, first_frame, num_frames, capacity, "max_objects")
    t = table.frames - first_frame
    boxes = np.tile(np.asarray(PAD_BOX, np.float32), (num_frames, capacity, 1))
    ids = np.full((num_frames, capacity), -1, np.int32)
    mask = np.zeros((num_frames, capacity), bool)
    ignored = np.zeros((num_frames, capacity), bool)
    boxes[t, slot] = table.boxes
    ids[t, slot] = table.ids
    mask[t, slot] = True
    ignored[t, slot] = table.ignored
    return GroundTruth(boxes=boxes, ids=ids, mask=mask, ignored=ignored)


def _slots(table, first_frame, num_frames, capacity, name):
    """Slot index of each row within its frame, and the capacity to use."""
    t = table.frames - first_frame
    outside = (t < 0) | (t >= num_frames)
    if np.any(outside):
        i = int(np.argmax(outside))
        raise InputError(
            f"row for frame {table.frames[i]} lies outside frames "
            f"{first_frame}..{first_frame + num_frames - 1}"
        )
    counts = np.bincount(t, minlength=num_frames)
    largest = int(counts.max()) if counts.size else 0
    if capacity is None:
        capacity = max(largest, 1)
    elif largest > capacity:
        frame = first_frame + int(np.argmax(counts))
        source = f" in {table.path}" if table.path else ""
        raise InputError(
            f"frame {frame}{source} has {largest} rows but {name}={capacity}; "
            f"raise {name} to at least {largest}"
        )
    order = np.argsort(t, kind="stable")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    slot = np.empty_like(t)
    slot[order] = np.arange(t.shape[0]) - starts[t[order]]
    return slot, capacity


def load_sequence(
    path: str | Path,
    frames: tuple[int, int] | None = None,
    max_detections: int | None = None,
    max_objects: int | None = None,
) -> MotSequence:
    """Loads a MOTChallenge sequence folder.

    Reads ``seqinfo.ini``, ``det/det.txt`` and, when present, ``gt/gt.txt``, validating every
    row against the rules of :func:`read_mot_file` with the sequence's length and image size.
    Warns (:class:`~jaxtrack.errors.InputWarning`) when ``det.txt`` is empty, holds nothing
    in the span, or when no det or gt row lies in the second half of ``1..seqLength``.

    Args:
        path: the sequence folder.
        frames: ``(start, end)``, 1-based inclusive span to keep; default: the whole sequence.
        max_detections: detection capacity per frame; default: the largest count in the span.
        max_objects: ground-truth capacity per frame; default: the largest count in the span.

    Returns:
        The sequence with host-side tables and padded PyTrees for the span.

    Raises:
        FileFormatError: a missing or malformed file (names the file and line).
        InputError: a bad frame span or a capacity smaller than the data needs.
    """
    path = Path(path)
    if not path.is_dir():
        raise FileFormatError(path, None, "sequence folder not found")
    info = read_seqinfo(path / "seqinfo.ini")
    first, last = parse_frame_span(frames, info.seq_length)
    det_path = path / "det" / "det.txt"
    det_file = read_mot_file(det_path, "det", info=info)
    gt_path = path / "gt" / "gt.txt"
    gt_file = read_mot_file(gt_path, "gt", info=info) if gt_path.exists() else None
    _warn_about_coverage(det_path, det_file, gt_file, info)
    det_table = det_file.frame_span(first, last)
    if len(det_file) and not len(det_table):
        warnings.warn(
            InputWarning(f"{det_path} holds no detections in frames {first}..{last}"),
            stacklevel=2,
        )
    num_frames = last - first + 1
    gt_table = None if gt_file is None else gt_file.frame_span(first, last)
    check_memory(
        padded_sequence_bytes(
            num_frames,
            max_detections or _largest_count(det_table),
            0 if gt_table is None else max_objects or _largest_count(gt_table),
        ),
        f"loading {path} (frames {first}..{last})",
        "a shorter --frames span",
    )
    ground_truth = None
    if gt_table is not None:
        ground_truth = pad_ground_truth(gt_table, first, num_frames, max_objects)
    return MotSequence(
        path=path,
        info=info,
        first_frame=first,
        last_frame=last,
        det_table=det_table,
        gt_table=gt_table,
        detections=pad_detections(det_table, first, num_frames, max_detections),
        ground_truth=ground_truth,
    )


def _largest_count(table: MotTable) -> int:
    """The most rows any frame of ``table`` holds (the padded capacity; at least 1)."""
    return max(1, int(np.unique(table.frames, return_counts=True)[1].max(initial=0)))


def _warn_about_coverage(det_path, det: MotTable, gt: MotTable | None, info) -> None:
    """Warns when a det file is empty, or when no row lies in the second half of the frames."""
    if len(det) == 0:
        warnings.warn(
            InputWarning(f"{det_path} holds no detections: tracking it gives no tracks"),
            stacklevel=3,
        )
        return
    last = max(int(det.frames.max()), 0 if gt is None or len(gt) == 0 else int(gt.frames.max()))
    if 2 * last < info.seq_length:
        warnings.warn(
            InputWarning(
                f"seqLength is {info.seq_length} but the last row of {det_path}"
                f"{'' if gt is None else ' and gt.txt'} is on frame {last}: is seqLength right?"
            ),
            stacklevel=3,
        )


def parse_frame_span(frames, seq_length: int) -> tuple[int, int]:
    """Validates a 1-based inclusive frame span; accepts None, ``(a, b)`` or ``"a:b"``.

    In the string form either end may be omitted (``"401:"`` means 401 to the end).
    """
    if frames is None:
        return 1, seq_length
    if isinstance(frames, str):
        parts = frames.split(":")
        if len(parts) != 2:
            raise InputError(f"frame span must look like A:B, got {frames!r}")
        try:
            start = int(parts[0]) if parts[0].strip() else 1
            end = int(parts[1]) if parts[1].strip() else seq_length
        except ValueError:
            raise InputError(f"frame span must be two integers A:B, got {frames!r}") from None
    elif isinstance(frames, SequenceABC) and len(frames) == 2:
        start, end = int(frames[0]), int(frames[1])
    else:
        raise InputError(f"frame span must be (start, end), got {frames!r}")
    if not 1 <= start <= end <= seq_length:
        raise InputError(
            f"frame span {start}:{end} must satisfy 1 <= start <= end <= {seq_length} (seqLength)"
        )
    return start, end


def _read_text(path: Path) -> str:
    if not path.is_file():
        raise FileFormatError(path, None, "file not found")
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as err:
        line = path.read_bytes()[: err.start].count(b"\n") + 1
        raise FileFormatError(path, line, "not UTF-8 text") from None


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _format_number(value: float) -> str:
    return np.format_float_positional(float(value), trim="-")


def _column_name(index: int) -> str:
    name = _COLUMN_NAMES[index] if index < len(_COLUMN_NAMES) else "extra"
    return f"column {index + 1} ({name})"


def _row_text(row: np.ndarray) -> str:
    return ",".join(_format_number(v) for v in row)
