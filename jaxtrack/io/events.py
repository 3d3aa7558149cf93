"""Per-tracker event files: ``RES.events.csv`` beside a tracker's ``RES.txt``.

A CSV file with the header ``frame,id,event`` and one row per output identity and frame:
the 1-based frame, the identity of ``RES.txt`` and the event's name, one of
:data:`~jaxtrack.filters.hier_events.EVENT_NAMES` (``single``, ``grouping``, ``grouped``,
``splitting``, ``entering``, ``exiting``; Hierarchical Sec. 5.5)::

    frame,id,event
    1,1,entering
    1,2,single

Rows are written sorted by frame, then id.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.filters.hier_events import EVENT_NAMES
from jaxtrack.metrics.events import EventRows

#: The header line of an events file.
HEADER = "frame,id,event"


def events_path(results_path: str | Path) -> Path:
    """``RES.events.csv`` beside ``RES.txt``: the results path with ``.txt`` replaced.

    Raises:
        InputError: ``results_path`` does not end in ``.txt``.
    """
    path = Path(results_path)
    if path.suffix != ".txt":
        raise InputError(f"{path}: a results file must end in .txt to name its events file")
    return path.with_suffix(".events.csv")


def write_events(path: str | Path, rows: EventRows) -> Path:
    """Writes an events file (module docstring).

    Args:
        path: the file to write.
        rows: the rows; each name one of ``EVENT_NAMES``, one row per frame and identity.

    Returns:
        ``path``.

    Raises:
        InputError: an unknown event name, or an identity twice on one frame.
    """
    unknown = sorted(set(rows.names.tolist()) - set(EVENT_NAMES))
    if unknown:
        raise InputError(f"unknown event name {unknown[0]!r}; expected one of {EVENT_NAMES}")
    order = np.lexsort((rows.ids, rows.frames))
    frames, ids = rows.frames[order], rows.ids[order]
    repeated = np.flatnonzero((frames[1:] == frames[:-1]) & (ids[1:] == ids[:-1]))
    if repeated.size:
        k = repeated[0]
        raise InputError(f"identity {ids[k]} has two events on frame {frames[k]}")
    lines = [HEADER] + [
        f"{f},{i},{name}" for f, i, name in zip(frames, ids, rows.names[order], strict=True)
    ]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path


def read_events(path: str | Path) -> EventRows:
    """Reads an events file (module docstring).

    Raises:
        FileFormatError: naming the file and line: missing file, wrong header, a row without
            three columns, a frame below 1 or a non-integer frame or id, an unknown event
            name, an identity twice on one frame.
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except FileNotFoundError:
        raise FileFormatError(path, None, "events file not found") from None
    except UnicodeDecodeError:
        raise FileFormatError(path, None, "not UTF-8 text") from None
    if not lines or lines[0].strip() != HEADER:
        raise FileFormatError(path, 1, f"the first line must be the header {HEADER!r}")
    frames, ids, names, seen = [], [], [], {}
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        frame, identity, name = _row(path, number, line)
        if (frame, identity) in seen:
            raise FileFormatError(
                path,
                number,
                f"identity {identity} already has an event on frame {frame} "
                f"(line {seen[frame, identity]})",
            )
        seen[frame, identity] = number
        frames.append(frame)
        ids.append(identity)
        names.append(name)
    return EventRows(
        frames=np.array(frames, np.int64),
        ids=np.array(ids, np.int64),
        names=np.array(names, dtype=f"<U{max(map(len, EVENT_NAMES))}"),
    )


def _row(path: Path, number: int, line: str) -> tuple[int, int, str]:
    """One parsed row ``(frame, id, name)``; FileFormatError naming the line when bad."""
    fields = [field.strip() for field in line.split(",")]
    if len(fields) != 3:
        raise FileFormatError(path, number, f"expected 3 columns (frame,id,event), got {line!r}")
    try:
        frame, identity = int(fields[0]), int(fields[1])
    except ValueError:
        raise FileFormatError(
            path, number, f"frame and id must be integers, got {line!r}"
        ) from None
    if frame < 1:
        raise FileFormatError(path, number, f"frames are 1-based, got {frame}")
    if fields[2] not in EVENT_NAMES:
        raise FileFormatError(
            path, number, f"unknown event {fields[2]!r}; expected one of {', '.join(EVENT_NAMES)}"
        )
    return frame, identity, fields[2]
