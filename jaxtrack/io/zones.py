"""Scene zones files: ``zones.json`` and its activity mask PNG (``jaxtrack learn-zones``).

The JSON file (format version 1)::

    {
      "format_version": 1,
      "image_width": 768,
      "image_height": 576,
      "zones": [{"x": 690.2, "y": 197.0, "w": 77.8, "h": 214.4, "entries": 13, "exits": 8}],
      "activity_mask": "zones.activity.png",
      "activity_cell": 8,
      "source": {"sequence": "PETS09-S2L1", "frames": [1, 795], "from": "gt"}
    }

Each zone is an entry/exit zone, an axis-aligned box ``x, y, w, h`` (top-left corner,
pixels) of *foot points*, the middles of the boxes' bottom edges
(:mod:`jaxtrack.context.zones`); ``entries`` and ``exits`` (the
training trajectories that started / ended in it) or ``share`` (of a birth intensity's
density) are optional. ``activity_mask`` names a grey PNG beside the JSON file (a path
relative to the JSON file's folder), one pixel per cell of ``activity_cell`` pixels,
non-zero where the scene is active, of ``ceil(image_height / cell)`` rows and
``ceil(image_width / cell)`` columns; ``null`` when the zones come from a birth intensity
(no trajectories, no mask). ``source`` records how the zones were made (free-form).
Trackers read the file with :func:`load_zones` (``--zones zones.json``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

from jaxtrack.context.activity import grid_shape
from jaxtrack.context.zones import SceneZones
from jaxtrack.errors import FileFormatError, InputError, check_keys
from jaxtrack.limits import IMAGE_SIZE, MAX_IMAGE_SIZE

#: Version written into (and required from) a zones file.
FORMAT_VERSION = 1
#: Keys of the top-level object: required, then optional.
REQUIRED_KEYS = ("format_version", "image_width", "image_height", "zones", "activity_mask")
OPTIONAL_KEYS = ("activity_cell", "source")
#: Keys of a zone: required, then optional.
ZONE_KEYS = ("x", "y", "w", "h")
ZONE_DETAILS = ("entries", "exits", "share")
#: Slack on "inside the image" for zone boxes written with rounding, pixels.
IMAGE_SLACK = 1e-6


def activity_file(path: str | Path) -> Path:
    """The activity mask PNG written beside a zones file: ``<stem>.activity.png``."""
    path = Path(path)
    return path.with_name(f"{path.stem}.activity.png")


def save_zones(
    path: str | Path,
    zones: SceneZones,
    image_size: tuple[int, int],
    details: list[dict] | None = None,
    source: dict | None = None,
) -> list[Path]:
    """Writes a zones file and, when the zones have one, its activity mask PNG.

    Args:
        path: the ``.json`` file (its folder is created if needed); the mask goes to
            :func:`activity_file` of it.
        zones: the zones.
        image_size: ``(width, height)`` of the image, pixels.
        details: per zone, optional keys of :data:`ZONE_DETAILS` (e.g. ``entries``).
        source: how the zones were made (JSON-serialisable).

    Returns:
        The files written (the JSON file first).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    details = details or [{} for _ in range(len(zones.boxes))]
    boxes = np.asarray(zones.boxes, np.float64).reshape(-1, 4)
    entries = [
        {**dict(zip(ZONE_KEYS, (round(float(v), 3) for v in box), strict=True)), **extra}
        for box, extra in zip(boxes, details, strict=True)
    ]
    written = [path]
    mask_name = None
    if zones.activity is not None:
        mask = activity_file(path)
        cv2.imwrite(str(mask), np.where(np.asarray(zones.activity), 255, 0).astype(np.uint8))
        mask_name = mask.name
        written.append(mask)
    data = {
        "format_version": FORMAT_VERSION,
        "image_width": int(image_size[0]),
        "image_height": int(image_size[1]),
        "zones": entries,
        "activity_mask": mask_name,
    }
    if zones.activity is not None:
        data["activity_cell"] = zones.cell_size
    if source is not None:
        data["source"] = source
    path.write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
    return written


def load_zones(path: str | Path) -> SceneZones:
    """Reads and validates a zones file and its activity mask.

    Args:
        path: the JSON file.

    Returns:
        The zones (boxes ``[num_zones, 4]`` float64; the mask as a boolean array, or None).

    Raises:
        FileFormatError: naming the file (and the line for JSON syntax errors, the key such as
            ``zones[2].w`` for bad content): a missing file, invalid JSON, a missing or
            unknown key, another ``format_version``, a bad image size, a zone that is not
            four finite numbers with positive size inside the image, a missing or bad
            ``activity_cell``; or naming the mask PNG: missing, unreadable, not grey, or not
            of the grid's size.
    """
    path = Path(path)
    if not path.is_file():
        raise FileFormatError(path, None, "zones file not found")
    try:
        data = json.loads(path.read_text(encoding="utf-8"), parse_constant=_reject_constant)
    except UnicodeDecodeError:
        raise FileFormatError(path, None, "not UTF-8 text") from None
    except json.JSONDecodeError as err:
        raise FileFormatError(path, err.lineno, f"not valid JSON: {err.msg}") from None
    except ValueError as err:
        raise FileFormatError(path, None, str(err)) from None
    try:
        boxes, mask_name, cell, size = _check(data)
    except InputError as err:
        raise FileFormatError(path, None, str(err)) from None
    activity = None
    if mask_name is not None:
        activity = _read_mask(path.parent / mask_name, grid_shape(*size, cell), path)
    return SceneZones(
        boxes=boxes, activity=activity, cell_size=None if cell is None else float(cell)
    )


def _check(data) -> tuple[np.ndarray, str | None, float | None, tuple[int, int]]:
    """``(boxes, mask name, cell, (width, height))`` of parsed JSON; InputError naming the key."""
    if not isinstance(data, dict):
        raise InputError("top level must be a JSON object")
    check_keys(data, REQUIRED_KEYS, OPTIONAL_KEYS)
    version = data["format_version"]
    if isinstance(version, bool) or version != FORMAT_VERSION:
        raise InputError(f"format_version must be {FORMAT_VERSION}, got {json.dumps(version)}")
    width = IMAGE_SIZE.check("image_width", data["image_width"])
    height = IMAGE_SIZE.check("image_height", data["image_height"])
    zones = data["zones"]
    if not isinstance(zones, list):
        raise InputError("zones must be a list of {'x':, 'y':, 'w':, 'h':} objects")
    boxes = np.asarray([_zone(zone, f"zones[{i}]", width, height) for i, zone in enumerate(zones)])
    mask_name = data["activity_mask"]
    cell = data.get("activity_cell")
    if mask_name is None:
        if cell is not None:
            raise InputError("activity_cell is given but activity_mask is null")
    else:
        if not isinstance(mask_name, str) or not mask_name:
            raise InputError(f"activity_mask must be a file name or null, got {mask_name!r}")
        if cell is None:
            raise InputError("missing key 'activity_cell' (the mask's cell side, pixels)")
        if (
            isinstance(cell, bool)
            or not isinstance(cell, int | float)
            or not (1 <= cell <= MAX_IMAGE_SIZE)
        ):
            raise InputError(f"activity_cell must be a number of pixels >= 1, got {cell!r}")
    return boxes.reshape(-1, 4), mask_name, cell, (width, height)


def _zone(zone, where: str, width: int, height: int) -> list[float]:
    """The box of one zone entry, checked."""
    if not isinstance(zone, dict):
        raise InputError(f"{where} must be an object with the keys x, y, w, h")
    check_keys(zone, ZONE_KEYS, ZONE_DETAILS, where)
    box = []
    for key in ZONE_KEYS:
        value = zone[key]
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or not math.isfinite(value)
        ):
            raise InputError(f"{where}.{key} must be a finite number, got {json.dumps(value)}")
        box.append(float(value))
    x, y, w, h = box
    if w <= 0 or h <= 0:
        raise InputError(f"{where}: w and h must be positive, got w={w:g}, h={h:g}")
    inside = (
        x >= -IMAGE_SLACK
        and y >= -IMAGE_SLACK
        and x + w <= width + IMAGE_SLACK
        and y + h <= height + IMAGE_SLACK
    )
    if not inside:
        raise InputError(
            f"{where}: box ({x:g}, {y:g}, {w:g}, {h:g}) reaches outside the {width}x{height} image"
        )
    return box


def _read_mask(mask_path: Path, shape: tuple[int, int], zones_path: Path) -> np.ndarray:
    """The activity mask as booleans, checked against the grid's ``(rows, columns)``."""
    named = f"activity mask of {zones_path}"
    if not mask_path.is_file():
        raise FileFormatError(mask_path, None, f"{named} not found")
    image = cv2.imread(str(mask_path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise FileFormatError(mask_path, None, f"{named}: not a readable image")
    if image.ndim != 2:
        raise FileFormatError(mask_path, None, f"{named}: must be a grey image, got {image.shape}")
    if image.shape != shape:
        raise FileFormatError(
            mask_path,
            None,
            f"{named}: {image.shape[0]}x{image.shape[1]} cells (rows x columns), expected "
            f"{shape[0]}x{shape[1]} for the image size and activity_cell",
        )
    return image > 0


def _reject_constant(name: str):
    raise ValueError(f"{name} is not allowed in a zones file")
