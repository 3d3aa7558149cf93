"""Typed configuration of the synthetic surveillance scenes (:mod:`jaxtrack.datasets.synthetic`).

Three frozen dataclasses: :class:`EntryZone` (where and how targets are born),
:class:`ClutterSource` (a localised, spatially persistent source of false detections) and
:class:`SceneConfig` (everything else). The defaults describe a 768x576 plaza seen by a
surveillance camera at 10 frames/s: four zones on the image border, a doorway inside the
image, three clutter sources (waving vegetation, a bush, a window reflection) and weak uniform
clutter, with about ten targets in view.

Beyond the defaults (which the learner's own model family fits exactly), a zone can be an edge
or a wide gateway (``extent``), give births of another object class (``height_scale``,
``aspect_ratio``: cars beside pedestrians) and be open only during some frames
(``active_frames``); a clutter source can cover a patch (``extent``) and flicker on and off
(``on_frames``, ``off_frames``). :mod:`jaxtrack.datasets.scene_bank` builds scene families
from them.

Units: positions and sizes in pixels, velocities in pixels/frame, rates in expected events
per frame. A configuration round-trips through JSON with :func:`config_to_dict` and
:func:`config_from_dict` (the latter also applies partial overrides to a base config);
:func:`load_scene_config` reads a JSON file.

Every numeric field has one rule (:data:`SCENE_RULES`, :data:`ZONE_RULES`,
:data:`SOURCE_RULES`; :class:`jaxtrack.limits.Rule`: finite, float32-representable, in its
range). The ranges keep a simulation finite and its output readable by jaxtrack's own readers:
``num_frames`` and frame counts at most 10^6, image sides ``16..65536``, frame rate
``1..1000``, ``birth_rate <= 10`` births per frame, false detections at most 100 per frame
(uniform and sources together), at most 100 zones and 100 sources, coordinates within
``+-2^20`` pixels, standard deviations at least 1/1000 (the written boxes are rounded to
1/1000 pixel), box sizes at least 1 pixel and ``max_box_size`` (and the perspective law's
boxes at the image bottom) at most 10 image sizes, relative noises in ``[0, 1]``,
``|size_correlation| <= 0.99`` (the birth covariances stay positive definite in float32),
extents at least 0 (a zone's rectangle inside the image), class height scales and aspect
ratios in ``[0.01, 100]``, flicker periods ``on_frames >= 1`` and ``off_frames`` 0 or >= 1.
Invalid values raise :class:`jaxtrack.errors.InputError` naming the field.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from jaxtrack.configs import read_json_file
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.limits import (
    FRAME_COUNT,
    FRAME_RATE,
    IMAGE_FACTOR,
    IMAGE_SIZE,
    MAX_COORDINATE,
    MAX_FRAMES,
    MIN_BOX_SIZE,
    Rule,
)

Pair = tuple[float, float]


#: Largest expected births per frame of a scene (about 10 * the mean lifetime targets in view).
MAX_BIRTH_RATE = 10.0
#: Largest expected false detections per frame of a scene (uniform and sources together).
MAX_CLUTTER_RATE = 100.0
#: Most entry zones, and most clutter sources, of a scene.
MAX_PARTS = 100
#: Smallest standard deviation of a position, size or velocity: the written boxes are rounded
#: to 1/1000 pixel, so a smaller spread is not a spread.
MIN_STD = 1e-3

_COORDINATE = Rule("pixels", float, -MAX_COORDINATE, MAX_COORDINATE)
_COORDINATES = Rule("pixels", tuple, -MAX_COORDINATE, MAX_COORDINATE, length=2)
_STDS = Rule("standard deviations", tuple, MIN_STD, MAX_COORDINATE, length=2)
_FRACTION = Rule("a probability or fraction", float, 0.0, 1.0)
_NOISES = Rule("relative noise levels", tuple, 0.0, 1.0, length=2)
_BOX_SIZES = Rule("box width and height, pixels", tuple, MIN_BOX_SIZE, MAX_COORDINATE, length=2)
_BETA = Rule("Beta distribution parameters", tuple, 0.01, 1000.0, length=2)
_EXTENT = Rule("half-sizes of a uniform rectangle, pixels", tuple, 0.0, MAX_COORDINATE, length=2)
_ASPECT = Rule("width / height", float, 0.01, 100.0)
#: A frame number of a simulation: burn-in frames are numbered ``1 - burn_in_frames .. 0``.
_SIMULATED_FRAME = Rule("frame number (burn-in frames <= 0)", int, -MAX_FRAMES, MAX_FRAMES)
_PERIOD = Rule("mean frames", float, 0.0, MAX_FRAMES)

#: The rule of every numeric field of :class:`EntryZone`.
ZONE_RULES: dict[str, Rule] = {
    "centre": _COORDINATES,
    "position_std": _STDS,
    "velocity": _COORDINATES,
    "velocity_std": _STDS,
    "weight": Rule("relative share of the births", float, 0.0, 1e6, lower_open=True),
    "extent": _EXTENT,
    "height_scale": Rule("height / the perspective law's height", float, 0.01, 100.0),
    "aspect_ratio": _ASPECT,
}
#: The rule of every numeric field of :class:`ClutterSource`.
SOURCE_RULES: dict[str, Rule] = {
    "centre": _COORDINATES,
    "position_std": _STDS,
    "size": _BOX_SIZES,
    "size_std": _STDS,
    "rate": Rule("false detections per frame", float, 0.0, MAX_CLUTTER_RATE),
    "extent": _EXTENT,
    "on_frames": Rule("mean frames", float, 1.0, MAX_FRAMES),
    "off_frames": _PERIOD,
}
#: The rule of every numeric field of :class:`SceneConfig` (cross-field rules: see there).
SCENE_RULES: dict[str, Rule] = {
    "num_frames": FRAME_COUNT,
    "image_width": IMAGE_SIZE,
    "image_height": IMAGE_SIZE,
    "frame_rate": FRAME_RATE,
    "burn_in_frames": Rule("frames simulated before frame 1", int, 0, MAX_FRAMES),
    "birth_rate": Rule("births per frame", float, 0.0, MAX_BIRTH_RATE),
    "horizon_row": _COORDINATE,
    "height_per_row": Rule("pixels of height per row", float, 0.0, 100.0, lower_open=True),
    "aspect_ratio": _ASPECT,
    "size_spread": Rule("relative size spread", float, 0.0, 1.0, lower_open=True),
    "size_correlation": Rule("correlation", float, -0.99, 0.99),
    "motion_noise": _NOISES,
    "size_noise": _NOISES,
    "size_reversion": _FRACTION,
    "exit_radius": Rule("standard deviations", float, 0.0, 100.0, lower_open=True),
    "min_exit_age": Rule("frames", int, 0, MAX_FRAMES),
    "detection_prob": _FRACTION,
    "misplaced_detection_prob": _FRACTION,
    "extra_detection_prob": _FRACTION,
    "occluded_detection_prob": _FRACTION,
    "occlusion_threshold": _FRACTION,
    "measurement_noise": _NOISES,
    "uniform_clutter_rate": Rule("false detections per frame", float, 0.0, MAX_CLUTTER_RATE),
    "min_box_size": _BOX_SIZES,
    "max_box_size": _BOX_SIZES,
    "velocity_bound": Rule("pixels per frame", float, 0.0, MAX_COORDINATE, lower_open=True),
    "target_score": _BETA,
    "clutter_score": _BETA,
}


def apply_rules(instance, rules: dict[str, Rule], where: str, optional=()) -> None:
    """Checks (and normalises: ints, floats, tuples) every ruled field of a frozen dataclass.

    A field named in ``optional`` may also be None (not checked).
    """
    for field, rule in rules.items():
        value = getattr(instance, field)
        if value is None and field in optional:
            continue
        object.__setattr__(instance, field, rule.check(f"{where}{field}", value))


@dataclasses.dataclass(frozen=True)
class EntryZone:
    """An entry (and optionally exit) zone: where, how and what kind of targets are born.

    A birth in this zone has its centre drawn from ``N(centre, diag(position_std^2))`` plus,
    when ``extent`` is not zero, an offset uniform over the rectangle ``[-extent, extent]``
    (a whole image edge or a wide gateway is a segment, not a blob), and its centre velocity
    from ``N(velocity, diag(velocity_std^2))``; its size follows the perspective law of
    :class:`SceneConfig` scaled to the zone's object class (``height_scale``,
    ``aspect_ratio``; see ``synthetic.zone_birth_gaussian``). A zone may be open only during
    ``active_frames``. With the defaults of the last four fields a zone is one Gaussian
    component of the true birth intensity, of the scene's single object class, always open.

    Attributes:
        name: label used in plots and metadata.
        centre: mean box centre ``(y1, y2)`` (column, row) of a birth, pixels.
        position_std: standard deviation of the birth centre along ``(y1, y2)``, pixels.
        velocity: mean centre velocity ``(vy1, vy2)`` at birth, pixels/frame.
        velocity_std: standard deviation of the birth velocity, pixels/frame.
        weight: relative share of the births that enter here (normalised over zones).
        exit: when True the zone is also an exit: a target whose centre lies within
            ``SceneConfig.exit_radius`` standard deviations of ``centre`` leaves the scene
            (once older than ``SceneConfig.min_exit_age``). Zones on the image border do not
            need it: leaving the image ends a target anyway. With an ``extent`` the exit is
            the rectangle widened by ``exit_radius`` standard deviations.
        extent: half-width and half-height ``(e1, e2)`` of the rectangle of uniform birth
            centres around ``centre``, pixels; ``(0, e2)`` is a vertical segment (e.g. the
            left image edge), ``(e1, 0)`` a horizontal one.
        height_scale: the object class's height relative to the scene's perspective law (a
            car is lower than a standing person: about 0.8).
        aspect_ratio: the object class's width / height (a pedestrian about 0.4, a car seen
            from the side about 2.5); None: the scene's ``aspect_ratio``.
        active_frames: ``(first, last)``, the frames in which the zone gives births (inclusive;
            burn-in frames are numbered ``1 - burn_in_frames .. 0``); None: every frame. The
            zone's share of ``SceneConfig.birth_rate`` is simply absent outside them (the
            other zones keep their rates). Exits work in every frame.
    """

    name: str
    centre: Pair
    position_std: Pair
    velocity: Pair
    velocity_std: Pair
    weight: float = 1.0
    exit: bool = False
    extent: Pair = (0.0, 0.0)
    height_scale: float = 1.0
    aspect_ratio: float | None = None
    active_frames: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        where = f"zone {self.name!r} "
        apply_rules(self, ZONE_RULES, where, optional=("aspect_ratio",))
        if self.active_frames is not None:
            if not isinstance(self.active_frames, list | tuple) or len(self.active_frames) != 2:
                raise InputError(
                    f"{where}active_frames must be a list of 2 frame numbers, "
                    f"got {self.active_frames!r}"
                )
            first, last = (
                _SIMULATED_FRAME.check(f"{where}active_frames[{i}]", frame)
                for i, frame in enumerate(self.active_frames)
            )
            if first > last:
                raise InputError(f"{where}active_frames: first {first} after last {last}")
            object.__setattr__(self, "active_frames", (first, last))

    def is_active(self, frame: int) -> bool:
        """Whether the zone gives births in ``frame``."""
        frames = self.active_frames
        return frames is None or frames[0] <= frame <= frames[1]


@dataclasses.dataclass(frozen=True)
class ClutterSource:
    """A localised source of spatially persistent clutter (e.g. waving vegetation).

    Each frame in which the source is on it emits ``Poisson(rate)`` false detections,
    independently of the past, with box ``(cx, cy, w, h)`` drawn from ``N((centre, size),
    diag(position_std^2, size_std^2))``, the centre shifted by an offset uniform over
    ``[-extent, extent]`` when ``extent`` is not zero (a patch of vegetation rather than one
    swaying branch).

    **Flicker.** With ``off_frames > 0`` the source switches on and off (a reflection that
    comes and goes with the sun, a blinking sign, a screen): a two-state Markov chain whose on
    and off periods are geometric with means ``on_frames`` and ``off_frames``, started from its
    stationary law, on a fraction ``duty_cycle = on / (on + off)`` of the frames. With
    ``off_frames = 0`` (the default) the source is always on.

    Attributes:
        name: label used in plots and metadata.
        centre: mean box centre ``(cx, cy)``, pixels.
        position_std: standard deviation of the box centre, pixels.
        size: mean box ``(w, h)``, pixels.
        size_std: standard deviation of the box width and height, pixels.
        rate: expected false detections per frame while the source is on.
        extent: half-width and half-height of the rectangle of uniform box centres around
            ``centre``, pixels.
        on_frames: mean length of an on period, frames (>= 1; used when ``off_frames > 0``).
        off_frames: mean length of an off period, frames: 0 (always on) or >= 1.
    """

    name: str
    centre: Pair
    position_std: Pair
    size: Pair
    size_std: Pair
    rate: float
    extent: Pair = (0.0, 0.0)
    on_frames: float = 1.0
    off_frames: float = 0.0

    def __post_init__(self) -> None:
        where = f"clutter source {self.name!r} "
        apply_rules(self, SOURCE_RULES, where)
        if 0 < self.off_frames < 1:
            raise InputError(
                f"{where}off_frames must be 0 (always on) or >= 1, got {self.off_frames}"
            )

    @property
    def duty_cycle(self) -> float:
        """The fraction of frames the source is on, ``on_frames / (on_frames + off_frames)``."""
        return self.on_frames / (self.on_frames + self.off_frames)

    @property
    def mean_rate(self) -> float:
        """Expected false detections per frame averaged over on and off frames."""
        return self.rate * self.duty_cycle


DEFAULT_ZONES: tuple[EntryZone, ...] = (
    EntryZone("west", (40.0, 330.0), (6.0, 30.0), (4.5, 0.2), (0.6, 0.5), weight=0.3),
    EntryZone("east", (730.0, 260.0), (6.0, 30.0), (-4.5, 0.4), (0.6, 0.5), weight=0.25),
    EntryZone("south", (420.0, 490.0), (40.0, 6.0), (-0.5, -3.0), (0.8, 0.4), weight=0.2),
    EntryZone("north", (250.0, 60.0), (20.0, 5.0), (0.8, 2.5), (0.5, 0.4), weight=0.15),
    EntryZone("door", (560.0, 150.0), (8.0, 4.0), (-1.0, 2.0), (0.8, 0.4), weight=0.1, exit=True),
)

DEFAULT_CLUTTER_SOURCES: tuple[ClutterSource, ...] = (
    ClutterSource("tree", (130.0, 130.0), (12.0, 10.0), (34.0, 60.0), (6.0, 10.0), rate=0.6),
    ClutterSource("bush", (660.0, 480.0), (15.0, 8.0), (50.0, 70.0), (8.0, 10.0), rate=0.5),
    ClutterSource("window", (420.0, 210.0), (6.0, 6.0), (22.0, 48.0), (3.0, 6.0), rate=0.4),
)


@dataclasses.dataclass(frozen=True)
class SceneConfig:
    """Everything that defines a synthetic scene; see :mod:`jaxtrack.datasets.synthetic`.

    Attributes:
        name: sequence name written to ``seqinfo.ini``; None means ``"synthetic-<seed>"``.
        num_frames: number of frames ``T`` (numbered ``1..T``).
        image_width: image width ``W``, pixels.
        image_height: image height ``H``, pixels.
        frame_rate: frames per second (metadata only: dynamics are per frame).
        burn_in_frames: frames simulated before frame 1 so that frame 1 already holds a
            steady-state population (their births are not counted as births of the sequence).
        birth_rate: ``lambda_s``, expected births per frame over all zones (Poisson).
        zones: the entry/exit zones; every birth enters through one of them.
        horizon_row: row ``r0`` where the perspective law gives size 0, pixels (above the
            image when negative).
        height_per_row: ``a`` in the nominal height ``h_nom(y2) = a (y2 - r0)``, pixels of
            height per pixel of row.
        aspect_ratio: ``rho`` in the nominal width ``w_nom(y2) = rho h_nom(y2)``.
        size_spread: relative standard deviation (> 0) of a target's own size about the
            nominal one at birth (people differ in size).
        size_correlation: correlation of the relative width and height deviations at birth.
        motion_noise: ``(sigma_n1, sigma_n2)``, SPEC SDV acceleration noise per unit box width
            / height: the velocity ``vy1`` changes by ``w_{k-1} n1``, ``n1 ~ N(0, sigma_n1^2)``.
        size_noise: ``(sigma_nw, sigma_nh)``, per-frame standard deviation of the log
            width / height about the perspective law (the SDV size noise in log form).
        size_reversion: ``phi`` in ``[0, 1]``, per-frame persistence of the log-size
            deviation (1: random walk as in SPEC; smaller: faster return to the target's own
            size).
        exit_radius: size of an exit zone, in standard deviations of its position spread.
        min_exit_age: frames a target must have lived before an exit zone can absorb it.
        detection_prob: probability of detection ``pD`` of a target that is not occluded.
        occluded_detection_prob: ``pD`` of an occluded target.
        occlusion_threshold: a target is occluded when a target nearer the camera (larger
            box bottom row) covers more than this fraction of its box area.
        measurement_noise: ``(s_w, s_h)``: a detection of box ``(cx, cy, w, h)`` has noise
            standard deviations ``(s_w w, s_h h, s_w w, s_h h)`` (SPEC section 1 likelihood).
        clutter_sources: localised persistent clutter sources.
        uniform_clutter_rate: expected uniform false detections per frame; centre uniform
            over the image, size uniform over ``[min_box_size, max_box_size]``.
        min_box_size: ``(w, h)`` lower corner of the size range of the uniform volumes (birth
            and clutter intensities; uniform clutter sizes), pixels.
        max_box_size: ``(w, h)`` upper corner of that size range, pixels.
        velocity_bound: the birth intensity's volume spans velocities
            ``[-velocity_bound, velocity_bound]`` per axis, pixels/frame.
        target_score: ``(a, b)`` of the Beta distribution of true detections' scores.
        clutter_score: ``(a, b)`` of the Beta distribution of false detections' scores.
        misplaced_detection_prob: probability that a target's detection is *badly placed*
            instead of noisy about its box (a part of the person, a shifted box, a box
            spilling over a neighbour; :func:`jaxtrack.datasets.synthetic.badly_placed_boxes`),
            as real detectors do; 0 (default): never.
        extra_detection_prob: probability that a detected target also yields a second,
            badly placed box; 0 (default): never.
    """

    name: str | None = None
    num_frames: int = 800
    image_width: int = 768
    image_height: int = 576
    frame_rate: float = 10.0
    burn_in_frames: int = 300
    birth_rate: float = 0.06
    zones: tuple[EntryZone, ...] = DEFAULT_ZONES
    horizon_row: float = -150.0
    height_per_row: float = 0.16
    aspect_ratio: float = 0.4
    size_spread: float = 0.08
    size_correlation: float = 0.7
    motion_noise: Pair = (0.002, 0.001)
    size_noise: Pair = (0.01, 0.01)
    size_reversion: float = 0.9
    exit_radius: float = 2.0
    min_exit_age: int = 20
    detection_prob: float = 0.92
    occluded_detection_prob: float = 0.5
    occlusion_threshold: float = 0.3
    measurement_noise: Pair = (0.05, 0.04)
    clutter_sources: tuple[ClutterSource, ...] = DEFAULT_CLUTTER_SOURCES
    uniform_clutter_rate: float = 0.4
    min_box_size: Pair = (8.0, 16.0)
    max_box_size: Pair = (64.0, 150.0)
    velocity_bound: float = 8.0
    target_score: Pair = (6.0, 1.5)
    clutter_score: Pair = (3.0, 3.0)
    misplaced_detection_prob: float = 0.0
    extra_detection_prob: float = 0.0

    def __post_init__(self) -> None:
        apply_rules(self, SCENE_RULES, "")
        width, height = self.image_width, self.image_height
        if not all(lo < hi for lo, hi in zip(self.min_box_size, self.max_box_size, strict=True)):
            raise InputError(
                f"min_box_size {self.min_box_size} must be below max_box_size {self.max_box_size}"
            )
        if self.max_box_size[0] > IMAGE_FACTOR * width or self.max_box_size[1] > (
            IMAGE_FACTOR * height
        ):
            raise InputError(
                f"max_box_size {self.max_box_size} exceeds {IMAGE_FACTOR} times the "
                f"{width}x{height} image"
            )
        bottom_height = self.height_per_row * (height - self.horizon_row)
        if bottom_height > IMAGE_FACTOR * height or (
            self.aspect_ratio * bottom_height > IMAGE_FACTOR * width
        ):
            raise InputError(
                f"the perspective law gives {self.aspect_ratio * bottom_height:g}x"
                f"{bottom_height:g} boxes at the image bottom, more than {IMAGE_FACTOR} times "
                f"the {width}x{height} image; lower height_per_row or the horizon_row"
            )
        if self.total_clutter_rate > MAX_CLUTTER_RATE:
            raise InputError(
                f"uniform_clutter_rate plus the clutter sources' rates is "
                f"{self.total_clutter_rate:g} false detections per frame; at most "
                f"{MAX_CLUTTER_RATE:g}"
            )
        for field in ("zones", "clutter_sources"):
            if len(getattr(self, field)) > MAX_PARTS:
                raise InputError(f"{field}: at most {MAX_PARTS}, got {len(getattr(self, field))}")
        if not self.zones and self.birth_rate > 0:
            raise InputError("birth_rate > 0 needs at least one entry zone")
        for zone in self.zones:
            (y1, y2), (e1, e2) = zone.centre, zone.extent
            if not (0 <= y1 - e1 and y1 + e1 <= width and 0 <= y2 - e2 and y2 + e2 <= height):
                where = f"centre {zone.centre}"
                if e1 or e2:
                    where += f" +- extent {zone.extent}"
                raise InputError(f"zone {zone.name!r} {where} lies outside the image")
            top = y2 - e2
            if (
                zone.height_scale * self.height_per_row * (top - self.horizon_row)
                < (self.min_box_size[1])
            ):
                raise InputError(
                    f"zone {zone.name!r}: nominal height at row {top} is below min_box_size; "
                    "move the zone down or the horizon up"
                )
        names = [zone.name for zone in self.zones] + [s.name for s in self.clutter_sources]
        if len(set(names)) != len(names):
            raise InputError(f"zone and clutter source names must be distinct, got {names}")

    @property
    def total_clutter_rate(self) -> float:
        """Expected false detections per frame while every source is on (sources + uniform).

        Without flickering sources this is ``lambda_r``; see :attr:`mean_clutter_rate`.
        """
        return self.uniform_clutter_rate + sum(s.rate for s in self.clutter_sources)

    @property
    def mean_clutter_rate(self) -> float:
        """``lambda_r``: expected false detections per frame, averaged over the flicker."""
        return self.uniform_clutter_rate + sum(s.mean_rate for s in self.clutter_sources)


def config_to_dict(config: SceneConfig) -> dict[str, Any]:
    """The configuration as plain JSON-serialisable values (tuples become lists).

    Args:
        config: the configuration.

    Returns:
        A dict accepted back by :func:`config_from_dict`.
    """
    return to_plain(dataclasses.asdict(config))


def config_from_dict(overrides: Mapping[str, Any], base: SceneConfig | None = None) -> SceneConfig:
    """Builds a configuration from (possibly partial) plain values, e.g. parsed JSON.

    Keys override the fields of ``base``; ``zones`` and ``clutter_sources`` are replaced as a
    whole (a list of objects with the fields of :class:`EntryZone` / :class:`ClutterSource`).

    Args:
        overrides: field name -> value.
        base: the configuration overridden; default: ``SceneConfig()``.

    Returns:
        The new, validated configuration.

    Raises:
        InputError: an unknown field, a value of the wrong type or shape, or an invalid value.
    """
    return from_plain(SceneConfig, overrides, base or SceneConfig(), "config")


def load_scene_config(path: str | Path, base: SceneConfig | None = None) -> SceneConfig:
    """Reads a JSON object of scene fields (``simulate --scene-config``) over ``base``.

    Args:
        path: the JSON file.
        base: the configuration overridden; default: ``SceneConfig()``.

    Returns:
        The validated configuration.

    Raises:
        FileFormatError: naming the file (and the line of a JSON error), for a missing or
            unreadable file, invalid JSON, NaN or Infinity, JSON nested too deeply, something
            other than an object, or a field breaking its rule (named).
    """
    path = Path(path)
    data = read_json_file(path, "a scene configuration")
    if not isinstance(data, dict):
        raise FileFormatError(path, None, "expected a JSON object of scene configuration fields")
    try:
        return config_from_dict(data, base)
    except InputError as err:
        raise FileFormatError(path, None, str(err)) from None


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:30]}...({len(text)} characters)"


def to_plain(value):
    """A dataclass's ``asdict`` as plain JSON values (tuples become lists), recursively."""
    if isinstance(value, dict):
        return {key: to_plain(item) for key, item in value.items()}
    if isinstance(value, (tuple, list)):
        return [to_plain(item) for item in value]
    return value


def from_plain(cls, data, base, where: str):
    """A frozen dataclass ``cls`` from plain (JSON) values, over ``base`` when not None.

    Each value is converted to its field's annotation (numbers, strings, bools, tuples,
    optional fields, nested dataclasses, variable-length tuples of them); the dataclass's own
    ``__post_init__`` then checks its rules.

    Raises:
        InputError: naming ``where`` and the field, for an unknown field or a value of the
            wrong type or shape (and whatever the dataclass itself refuses).
    """
    if not isinstance(data, Mapping):
        raise InputError(f"{where} must be an object, got {type(data).__name__}")
    hints = typing.get_type_hints(cls)
    fields = {field.name for field in dataclasses.fields(cls)}
    unknown = sorted(set(data) - fields)
    if unknown:
        raise InputError(f"{where}: unknown field(s) {unknown}; valid fields: {sorted(fields)}")
    values = {}
    for name, raw in data.items():
        values[name] = _convert(hints[name], raw, f"{where}.{name}")
    try:
        if base is None:
            return cls(**values)
        return dataclasses.replace(base, **values)
    except TypeError as err:
        raise InputError(f"{where}: {err}") from None


def _convert(annotation, raw, where: str):
    origin = typing.get_origin(annotation)
    args = typing.get_args(annotation)
    if origin in (typing.Union, types.UnionType):
        if raw is None and type(None) in args:
            return None
        (inner,) = (arg for arg in args if arg is not type(None))
        return _convert(inner, raw, where)
    if origin is tuple:
        if not isinstance(raw, (list, tuple)):
            raise InputError(f"{where} must be a list, got {raw!r}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], item, f"{where}[{i}]") for i, item in enumerate(raw))
        if len(raw) != len(args):
            raise InputError(f"{where} must have {len(args)} entries, got {len(raw)}")
        return tuple(
            _convert(arg, item, f"{where}[{i}]")
            for i, (arg, item) in enumerate(zip(args, raw, strict=True))
        )
    if dataclasses.is_dataclass(annotation):
        return from_plain(annotation, raw, None, where)
    if annotation is bool:
        if not isinstance(raw, bool):
            raise InputError(f"{where} must be true or false, got {raw!r}")
        return raw
    if annotation is int:
        if isinstance(raw, float) and math.isfinite(raw) and raw.is_integer():
            return int(raw)
        if isinstance(raw, bool) or not isinstance(raw, int):
            raise InputError(f"{where} must be an integer, got {_short(raw)}")
        return raw
    if annotation is float:
        if isinstance(raw, bool) or not isinstance(raw, (int, float)):
            raise InputError(f"{where} must be a number, got {_short(raw)}")
        return raw  # the field's rule checks the range (and finiteness)
    if annotation is str:
        if not isinstance(raw, str):
            raise InputError(f"{where} must be a string, got {raw!r}")
        return raw
    raise TypeError(f"unsupported annotation {annotation!r} at {where}")
