"""Typed configuration of the scripted surveillance video (:mod:`jaxtrack.datasets.video_scene`).

Two frozen dataclasses: :class:`VideoZone` (an entry/exit zone) and :class:`VideoSceneConfig`
(everything else). The layout (zones, the ground's top row, the static occluder, the
vegetation, the bright patch, the perspective law) is given in **fractions of the image
size**, so that the same scene renders at any resolution: a 160x120 test video shows the same
people, events and frames as the 640x480 default, scaled. The written truth gives every box in
pixels.

A box is ``(x, y, w, h)``: left column, top row, width and height, as fractions of the image
width (``x``, ``w``) and height (``y``, ``h``). Rows grow downwards; the camera looks down on a
flat ground, so a person's **foot row** ``y_f`` (the bottom of the box) orders people from far
(small ``y_f``) to near.

The defaults describe a 640x480 plaza at 25 frames/s over 500 frames (20 s): a building wall
across the top with a door, entry/exit zones on the west and east edges, the south edge and the
door, a billboard (the occluder) right of centre, a tree's foliage in the top right corner and a
sunlit patch on the ground in the lower left.

A configuration round-trips through JSON (:func:`video_config_to_dict`,
:func:`video_config_from_dict`; :func:`load_video_config` reads a file). Every numeric field has
one rule (:data:`VIDEO_RULES`); cross-field rules are checked in
:meth:`VideoSceneConfig.__post_init__`. Invalid values raise
:class:`jaxtrack.errors.InputError` naming the field.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from jaxtrack.configs import read_json_file
from jaxtrack.datasets.scene_config import apply_rules, from_plain, to_plain
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.limits import FRAME_COUNT, FRAME_RATE, IMAGE_SIZE, Rule

Box = tuple[float, float, float, float]
Pair = tuple[float, float]

#: Most entry/exit zones of a video scene.
MAX_ZONES = 20
#: Most background walkers per zone (people are drawn one by one: a crowd is no test video).
MAX_WALKERS_PER_ZONE = 100
#: Values of :attr:`VideoSceneConfig.crossing_alike`: the clothes the crossing's pair share.
CROSSING_ALIKE = ("both", "top", "bottom")
#: A person's own height is drawn within this many ``height_spread`` of the nominal one.
HEIGHT_SPREAD_CLIP = 2.0

_BOX = Rule("(x, y, w, h) in image fractions", tuple, 0.0, 1.0, length=4)
_FRACTION = Rule("a probability or fraction", float, 0.0, 1.0)
_RATE = Rule("false detections per frame", float, 0.0, 100.0)

#: The rule of every numeric field of :class:`VideoSceneConfig`.
VIDEO_RULES: dict[str, Rule] = {
    "num_frames": FRAME_COUNT,
    "image_width": IMAGE_SIZE,
    "image_height": IMAGE_SIZE,
    "frame_rate": FRAME_RATE,
    "ground_row": Rule("image fraction", float, 0.0, 0.9),
    "horizon_row": Rule("image fraction", float, -10.0, 0.9),
    "height_per_row": Rule("person height per row of foot position", float, 0.01, 1.0),
    "aspect_ratio": Rule("width / height", float, 0.3, 0.6),
    "height_spread": Rule("relative standard deviation", float, 0.0, 0.2),
    "walking_pace": Rule("body heights per second", float, 0.1, 5.0),
    "walkers_per_zone": Rule("people", int, 0, MAX_WALKERS_PER_ZONE),
    "stand_frames": Rule("frames", int, 2, 100_000),
    "occluder": _BOX,
    "vegetation": _BOX,
    "bright_patch": _BOX,
    "noise_std": Rule("intensity levels (0-255)", float, 0.0, 50.0),
    "detection_prob": _FRACTION,
    "measurement_noise": Rule("relative noise levels", tuple, 0.0, 1.0, length=2),
    "clutter_rate": _RATE,
    "vegetation_clutter_rate": _RATE,
}


def _check_box(instance, field: str, where: str) -> None:
    """A box field: four fractions, a positive size, inside the image."""
    box = _BOX.check(f"{where}{field}", getattr(instance, field))
    x, y, w, h = box
    if w <= 0 or h <= 0 or x + w > 1 + 1e-9 or y + h > 1 + 1e-9:
        raise InputError(
            f"{where}{field} {box}: width and height must be positive and the box inside the "
            "image (x + w <= 1, y + h <= 1)"
        )
    object.__setattr__(instance, field, box)


@dataclasses.dataclass(frozen=True)
class VideoZone:
    """An entry/exit zone: where the feet of the people who enter or leave through it lie.

    A person entering here appears with its foot point (bottom centre of its box) inside
    ``box``; a person leaving here walks until its foot point reaches a point inside ``box``
    and disappears. Every zone is both an entry and an exit.

    Attributes:
        name: label used in the truth file and in messages.
        box: ``(x, y, w, h)`` in image fractions (see the module docstring).
    """

    name: str
    box: Box

    def __post_init__(self) -> None:
        _check_box(self, "box", f"zone {self.name!r} ")


DEFAULT_VIDEO_ZONES: tuple[VideoZone, ...] = (
    VideoZone("west", (0.0, 0.55, 0.0375, 0.12)),
    VideoZone("east", (0.9625, 0.45, 0.0375, 0.12)),
    VideoZone("south", (0.43, 0.92, 0.14, 0.05)),
    VideoZone("door", (0.46, 0.23, 0.05, 0.03)),
)


@dataclasses.dataclass(frozen=True)
class VideoSceneConfig:
    """Everything that defines a scripted video scene; see :mod:`~jaxtrack.datasets.video_scene`.

    Attributes:
        name: sequence name (``seqinfo.ini``, ``<name>.mp4``; :func:`check_video_name`);
            None: ``"video-<seed>"``.
        num_frames: number of frames ``T`` (numbered ``1..T``).
        image_width: frame width ``W``, pixels.
        image_height: frame height ``H``, pixels.
        frame_rate: frames per second (walking speed and gait are per second).
        zones: the entry/exit zones (at least 2, on the ground: ``y >= ground_row``; every
            person enters through one and leaves through another).
        ground_row: top row of the walkable ground (the foot of the back wall), fraction of
            ``H``; people's foot points stay at or below it.
        horizon_row: row ``r0`` where the perspective law gives height 0, fraction of ``H``
            (negative: above the image).
        height_per_row: ``a`` in the nominal height ``h(y_f) = a (y_f - r0)`` of a person
            whose feet are on row ``y_f`` (rows and heights in the same unit).
        aspect_ratio: ``rho``, box width / height.
        height_spread: relative standard deviation of a person's own height about ``h``
            (clipped to ``HEIGHT_SPREAD_CLIP`` of it).
        walking_pace: walking speed in body heights per second (about 0.8 for 1.4 m/s);
            each walker draws its own within +-15 %.
        walkers_per_zone: background walkers entering through each zone, at times spread over
            the scene (besides the scripted people).
        stand_frames: frames the standing person stands still.
        occluder: the static occluder (a billboard): a box in image fractions; people whose
            feet are above its bottom row are behind it.
        vegetation: the flickering foliage region (background-subtraction clutter).
        bright_patch: the box of the sunlit ellipse on the ground.
        noise_std: standard deviation of the Gaussian pixel noise, intensity levels.
        detection_prob: probability that ``det.txt`` holds a detection of a person at least
            half visible (lower when occluded, 0 below 20 % visible).
        measurement_noise: ``(s_w, s_h)``: a detection's ``(cx, cy, w, h)`` has noise
            standard deviations ``(s_w w, s_h h, s_w w, s_h h)``.
        clutter_rate: expected false detections per frame, uniform over the ground.
        vegetation_clutter_rate: expected false detections per frame in the vegetation
            while a gust moves it.
        crossing_alike: which clothes the scripted crossing's pair share (the same palette
            colour within +-4 levels): ``"both"`` (top and bottom: a near-identical pair, whose
            halves no colour feature separates), ``"top"`` or ``"bottom"`` (that half alike, the
            other half of the second person another palette colour: similarly dressed, with one
            separating feature, CMT paper's Fig. 9 case).
    """

    name: str | None = None
    num_frames: int = 500
    image_width: int = 640
    image_height: int = 480
    frame_rate: float = 25.0
    zones: tuple[VideoZone, ...] = DEFAULT_VIDEO_ZONES
    ground_row: float = 0.23
    horizon_row: float = -0.08
    height_per_row: float = 0.24
    aspect_ratio: float = 0.4
    height_spread: float = 0.05
    walking_pace: float = 0.8
    walkers_per_zone: int = 5
    stand_frames: int = 100
    occluder: Box = (0.66, 0.375, 0.14, 0.225)
    vegetation: Box = (0.8, 0.04, 0.2, 0.26)
    bright_patch: Box = (0.12, 0.69, 0.32, 0.18)
    noise_std: float = 4.0
    detection_prob: float = 0.9
    measurement_noise: Pair = (0.04, 0.03)
    clutter_rate: float = 0.2
    vegetation_clutter_rate: float = 1.5
    crossing_alike: str = "both"

    def __post_init__(self) -> None:
        apply_rules(self, VIDEO_RULES, "")
        if self.crossing_alike not in CROSSING_ALIKE:
            raise InputError(
                f"crossing_alike must be one of {', '.join(CROSSING_ALIKE)}, "
                f"got {self.crossing_alike!r}"
            )
        if self.name is not None:
            check_video_name(self.name)
        for field in ("occluder", "vegetation", "bright_patch"):
            _check_box(self, field, "")
        if not 2 <= len(self.zones) <= MAX_ZONES:
            raise InputError(f"zones: between 2 and {MAX_ZONES} zones, got {len(self.zones)}")
        names = [zone.name for zone in self.zones]
        if len(set(names)) != len(names):
            raise InputError(f"zone names must be distinct, got {names}")
        if self.horizon_row >= self.ground_row:
            raise InputError(
                f"horizon_row {self.horizon_row} must lie above ground_row {self.ground_row}"
            )
        for zone in self.zones:
            if zone.box[1] < self.ground_row:
                raise InputError(
                    f"zone {zone.name!r} reaches above the ground (its top {zone.box[1]:g} is "
                    f"above ground_row {self.ground_row:g}): people's feet stay on the ground"
                )
        if self.occluder[1] + self.occluder[3] <= self.ground_row:
            raise InputError(
                f"occluder {self.occluder}: its bottom must stand on the ground, below "
                f"ground_row {self.ground_row:g}"
            )
        tallest = self.person_height(1.0) * (1 + HEIGHT_SPREAD_CLIP * self.height_spread)
        if tallest > self.image_height:
            raise InputError(
                f"the perspective law gives {tallest:.0f}-pixel people at the image bottom, "
                f"more than the {self.image_height}-pixel image; lower height_per_row"
            )
        self._check_occluder()

    def pixels(self, box: Box) -> tuple[float, float, float, float]:
        """A box in image fractions as ``(x, y, w, h)`` pixels."""
        x, y, w, h = box
        width, height = self.image_width, self.image_height
        return x * width, y * height, w * width, h * height

    def person_height(self, foot_row: float) -> float:
        """Nominal height ``h = a (y_f - r0)`` in pixels of a person whose feet are on
        ``foot_row`` (a fraction of the image height)."""
        return self.height_per_row * (foot_row - self.horizon_row) * self.image_height

    def _check_occluder(self) -> None:
        """The occluder must be able to hide the tallest person standing right behind it."""
        _, _, w, h = self.pixels(self.occluder)
        base = (self.occluder[1] + self.occluder[3]) - 0.05 * self.occluder[3]
        person = self.person_height(base) * (1 + HEIGHT_SPREAD_CLIP * self.height_spread)
        if person > 0.9 * h or self.aspect_ratio * person > 0.6 * w:
            raise InputError(
                f"occluder {self.occluder} ({w:.0f}x{h:.0f} pixels) cannot hide a person "
                f"standing behind it ({self.aspect_ratio * person:.0f}x{person:.0f} pixels); "
                "it must be at least 1/0.9 of their height and 1/0.6 of their width"
            )


def check_video_name(name) -> str:
    """A sequence name that can name its video file ``<name>.mp4`` inside the folder.

    Raises:
        InputError: not a string, empty, ``.`` or ``..``, or holding a path separator or a
            control character (a new line would also break ``seqinfo.ini``).
    """
    if not isinstance(name, str):
        raise InputError(f"name must be a string, got {name!r}")
    if name in ("", ".", "..") or any(c in "/\\" or ord(c) < 32 for c in name):
        raise InputError(
            f"name {name!r} cannot name the video file <name>.mp4: it must be non-empty, not "
            "'.' or '..', without '/', '\\' or control characters"
        )
    return name


def video_config_to_dict(config: VideoSceneConfig) -> dict[str, Any]:
    """The configuration as plain JSON values (accepted back by :func:`video_config_from_dict`)."""
    return to_plain(dataclasses.asdict(config))


def video_config_from_dict(
    overrides: Mapping[str, Any], base: VideoSceneConfig | None = None
) -> VideoSceneConfig:
    """A configuration from (possibly partial) plain values over ``base``.

    Args:
        overrides: field name -> value; ``zones`` replaces the zones as a whole (a list of
            ``{"name": ..., "box": [x, y, w, h]}``).
        base: the configuration overridden; default ``VideoSceneConfig()``.

    Returns:
        The validated configuration.

    Raises:
        InputError: an unknown field, a value of the wrong type or shape, or an invalid value.
    """
    return from_plain(VideoSceneConfig, overrides, base or VideoSceneConfig(), "config")


def load_video_config(path: str | Path, base: VideoSceneConfig | None = None) -> VideoSceneConfig:
    """Reads a JSON object of video scene fields (``simulate --video --scene-config``).

    Raises:
        FileFormatError: naming the file, for a missing or unreadable file, invalid JSON,
            something other than an object, or a field breaking its rule (named).
    """
    path = Path(path)
    data = read_json_file(path, "a video scene configuration")
    if not isinstance(data, dict):
        raise FileFormatError(path, None, "expected a JSON object of video scene fields")
    try:
        return video_config_from_dict(data, base)
    except InputError as err:
        raise FileFormatError(path, None, str(err)) from None
