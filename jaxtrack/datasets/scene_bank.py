"""A bank of scene families that differ from the default scene the way real scenes do.

The default synthetic scene (:class:`~jaxtrack.datasets.scene_config.SceneConfig`) is drawn
from the model family that the context learner fits: Gaussian entry zones, Gaussian clutter
sources, one object class, a layout that never changes. A learner can look good there and
still fail on a real street (issue 15). Each family here is a function ``(seed) ->
SceneConfig`` (:data:`FAMILIES`) describing one kind of real scene; the seed draws the layout
(door and vegetation positions, lane rows, speeds, rates) from documented ranges, and
:func:`generate_family_scene` simulates it with the same seed (conditioned on an event for
one family, :data:`CONDITIONS`). Every family has
:data:`NUM_FRAMES` = 600 frames: the protocol learns context on the first half and tests on
the second (:func:`jaxtrack.experiments.common.split_halves`).

=================  ==================================================================
family             what it tests
=================  ==================================================================
``street``         mixed object classes (cars: wide, fast, on lanes entering along
                   the left and right road edges; pedestrians: narrow, slow, from a
                   door and along the sidewalks); static vegetation patches, one
                   flickering reflection and weak uniform clutter
``plaza-edges``    entries spread along whole image edges (uniform segments, which a
                   few Gaussian blobs fit badly) and lateral walking directions;
                   clutter mostly uniform
``sparse-door``    few births (15 expected in the training half, at 7 frames/s):
                   a learner must not over-fit a handful of events
``layout-change``  the test half's layout differs from the training half's: a door
                   closes and a gate opens at the half (a zone used only in the test
                   half), so learned birth context is partly wrong there
``flicker``        clutter dominated by sources that switch on and off (window
                   reflections, a blinking sign, a screen): persistent in place,
                   intermittent in time
``uniform``        no useful context: births anywhere in the image in any direction,
                   uniform clutter only; learned context can only match uniform
``misplaced``      a real detector's errors: boxes of people placed badly (parts,
                   shifted, spilling over a neighbour) and second boxes on a person,
                   which the IoU-0.5 evaluation counts as false positives although
                   targets produced them; they lie on the walking paths
=================  ==================================================================

**Parameters** are physical where they can be (not tuned to any tracker): object heights
follow each camera's perspective law (:class:`Camera`), widths an aspect ratio per object
class (:data:`PEDESTRIAN_ASPECT`, :data:`CAR_CLASS`); speeds are drawn in metres per second
(:data:`WALKING_SPEED`, :data:`CAR_SPEED`) and converted to pixels per frame at the row of
the zone with the pixels per metre of a :data:`PERSON_HEIGHT` person there; clutter boxes have
the size of a person at their row (detector false positives look like the objects it
detects). Detection and noise settings are the default scene's (``pD`` 0.92, 0.5 under
occlusion, measurement noise 5 % / 4 % of the box).

**True context** (``context_truth.npz``) of these scenes is the moment-matched, frame-averaged
approximation described in :mod:`jaxtrack.datasets.synthetic`: exact for Gaussian zones and
steady Gaussian sources, an approximation for edges, patches, flicker and zones that open or
close.
"""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Callable
from pathlib import Path

import numpy as np

from jaxtrack.datasets.scene_config import ClutterSource, EntryZone, SceneConfig
from jaxtrack.datasets.synthetic import SyntheticScene, generate_scene, write_scene
from jaxtrack.errors import InputError

#: Frames of every family's scene (learn on 1..300, test on 301..600).
NUM_FRAMES = 600
#: The seeds the bank is evaluated on.
SEEDS = (0, 1, 2)
#: Height of a standing person, metres: sets the pixels per metre at each row.
PERSON_HEIGHT = 1.7
#: Width / height of a pedestrian's box.
PEDESTRIAN_ASPECT = 0.4
#: Walking speeds, metres per second (range of a zone's mean speed).
WALKING_SPEED = (1.1, 1.6)
#: Urban car speeds in a street with pedestrians and a door, metres per second (16-27 km/h).
CAR_SPEED = (4.5, 7.5)
#: A car seen from the side: ``height_scale`` (about 1.45 m against a 1.7 m person) and
#: ``aspect_ratio`` (a 4.3 m car, slightly foreshortened).
CAR_CLASS = {"height_scale": 0.85, "aspect_ratio": 2.6}
#: Smallest box of every family's uniform volumes (and uniform clutter sizes).
MIN_BOX = (8.0, 16.0)
#: Frame rate at which the default scene's per-frame motion noise is kept (see
#: :meth:`Camera.config`).
REFERENCE_FRAME_RATE = 10.0


@dataclasses.dataclass(frozen=True)
class Camera:
    """A camera's image and perspective: the parts of a :class:`SceneConfig` a family shares.

    Attributes:
        width: image width, pixels.
        height: image height, pixels.
        frame_rate: frames per second.
        horizon_row: row where the perspective law gives height 0 (above the image).
        height_per_row: pixels of a person's height per row below the horizon.
    """

    width: int
    height: int
    frame_rate: float
    horizon_row: float
    height_per_row: float

    def person_height(self, row: float) -> float:
        """Box height of a standing person centred on ``row``, pixels."""
        return self.height_per_row * (row - self.horizon_row)

    def person_size(self, row: float) -> tuple[float, float]:
        """Box ``(w, h)`` of a standing person centred on ``row``, pixels."""
        height = self.person_height(row)
        return (PEDESTRIAN_ASPECT * height, height)

    def speed(self, row: float, metres_per_second: float) -> float:
        """A ground speed at ``row`` in pixels per frame (across the image)."""
        pixels_per_metre = self.person_height(row) / PERSON_HEIGHT
        return metres_per_second * pixels_per_metre / self.frame_rate

    def config(self, name: str, **fields) -> SceneConfig:
        """The scene configuration of this camera with the family's ``fields``.

        The motion noise is the default scene's per second: the SDV velocity is a random walk
        with per-frame steps ``sigma w``, so its spread after ``t`` seconds in pixels per
        second grows as ``sigma sqrt(t fps^3)``; the per-frame ``sigma`` is the default's
        times ``(10 / fps)^1.5`` (at 25 frames/s a quarter of it).
        """
        factor = (REFERENCE_FRAME_RATE / self.frame_rate) ** 1.5
        return SceneConfig(
            name=name,
            num_frames=NUM_FRAMES,
            image_width=self.width,
            image_height=self.height,
            frame_rate=self.frame_rate,
            horizon_row=self.horizon_row,
            height_per_row=self.height_per_row,
            aspect_ratio=PEDESTRIAN_ASPECT,
            min_box_size=MIN_BOX,
            motion_noise=tuple(factor * noise for noise in SceneConfig().motion_noise),
            **fields,
        )


def layout_rng(family: str, seed: int) -> np.random.Generator:
    """The generator of a family's layout: independent of the simulation's ``default_rng(seed)``.

    Args:
        family: the family's name.
        seed: the scene's seed.

    Returns:
        A NumPy generator seeded by ``(seed, crc32(family))``.
    """
    return np.random.default_rng([seed, zlib.crc32(family.encode())])


def _edge_walkers(
    camera: Camera, rng: np.random.Generator, row: float, half_width: float, weight: float
) -> tuple[EntryZone, EntryZone]:
    """Pedestrians entering along the left and right image edges over rows ``row +- half_width``."""
    zones = []
    for name, column, sign in (("west", 8.0, 1.0), ("east", camera.width - 8.0, -1.0)):
        speed = camera.speed(row, rng.uniform(*WALKING_SPEED))
        zones.append(
            EntryZone(
                f"walk-{name}-{row:.0f}",
                (column, row),
                (3.0, 3.0),
                (sign * speed, 0.0),
                (0.2 * speed, 0.1 * speed),
                weight=weight,
                extent=(0.0, half_width),
            )
        )
    return tuple(zones)


def _door(
    camera: Camera, rng: np.random.Generator, name: str, column: float, row: float, weight: float
) -> tuple[EntryZone, EntryZone]:
    """A door (also an exit): people come out and turn left or right (two zones, one place)."""
    zones = []
    for side, sign in (("l", -1.0), ("r", 1.0)):
        speed = camera.speed(row, rng.uniform(*WALKING_SPEED))
        zones.append(
            EntryZone(
                f"{name}-{side}",
                (column, row),
                (5.0, 3.0),
                (sign * 0.8 * speed, 0.3 * speed),
                (0.3 * speed, 0.2 * speed),
                weight=weight / 2,
                exit=True,
            )
        )
    return tuple(zones)


def _patch(
    camera: Camera, name: str, centre: tuple[float, float], extent, rate: float
) -> ClutterSource:
    """Vegetation (a hedge, a tree): person-sized false detections anywhere over a patch."""
    width, height = camera.person_size(centre[1])
    return ClutterSource(
        name,
        centre,
        (6.0, 6.0),
        (width, height),
        (0.2 * width, 0.15 * height),
        rate,
        extent=extent,
    )


def _static(
    camera: Camera,
    name: str,
    centre: tuple[float, float],
    rate: float,
    on_frames: float = 1.0,
    off_frames: float = 0.0,
) -> ClutterSource:
    """A static object a detector mistakes for a person (a reflection, a sign, a screen).

    Almost the same box every time it fires; it flickers when ``off_frames > 0``.
    """
    width, height = camera.person_size(centre[1])
    return ClutterSource(
        name,
        centre,
        (1.5, 1.5),
        (width, height),
        (0.05 * width, 0.05 * height),
        rate,
        on_frames=on_frames,
        off_frames=off_frames,
    )


def street(seed: int) -> SceneConfig:
    """A street with cars and pedestrians (the issue-15 kind of scene), 720x480 at 25 frames/s.

    Tests **mixed object classes and edge entries**: cars (:data:`CAR_CLASS`, 4.5-7.5 m/s)
    enter along the left edge on the near lane and the right edge on the far lane (vertical
    segments over the lane's width); pedestrians (1.1-1.6 m/s) come out of a door on the far
    side (an exit too) and walk in along both sidewalks. Half of the births are cars. Clutter
    (about 1.5 false detections per frame): two vegetation patches (0.3-0.6 each), a
    reflection in a shop window that flickers (on 30-80 frames, off 60-150 frames; 0.7-0.95
    per frame while on) and weak uniform clutter (0.2-0.4). About 18-24 births per half.

    Args:
        seed: draws the layout (lane rows, door and patch positions, speeds, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("street", seed)
    camera = Camera(720, 480, 25.0, horizon_row=-300.0, height_per_row=0.11)
    road = rng.uniform(220.0, 250.0)  # centre row of the road
    far_lane, near_lane = road - 14.0, road + 14.0
    far_walk, near_walk = road - 60.0, rng.uniform(380.0, 410.0)
    door = rng.uniform(150.0, 570.0)
    cars = []
    for name, column, row, sign in (
        ("car-west", 10.0, near_lane, 1.0),
        ("car-east", camera.width - 10.0, far_lane, -1.0),
    ):
        speed = camera.speed(row, rng.uniform(*CAR_SPEED))
        cars.append(
            EntryZone(
                name,
                (column, row),
                (3.0, 2.0),
                (sign * speed, 0.0),
                (0.08 * speed, 0.05),
                weight=0.25,
                extent=(0.0, 7.0),
                **CAR_CLASS,
            )
        )
    zones = (
        *cars,
        *_door(camera, rng, "door", door, far_walk - 12.0, 0.14),
        *_edge_walkers(camera, rng, near_walk, 25.0, 0.12),
        *_edge_walkers(camera, rng, far_walk, 10.0, 0.06),
    )
    reflection_column = door + rng.choice([-1.0, 1.0]) * rng.uniform(60.0, 140.0)
    sources = (
        _patch(
            camera,
            "hedge-far",
            (rng.uniform(100.0, 620.0), far_walk - 20.0),
            (rng.uniform(25.0, 40.0), rng.uniform(10.0, 20.0)),
            rng.uniform(0.3, 0.6),
        ),
        _patch(
            camera,
            "tree-near",
            (rng.uniform(100.0, 620.0), near_walk - 50.0),
            (rng.uniform(25.0, 40.0), rng.uniform(15.0, 25.0)),
            rng.uniform(0.3, 0.6),
        ),
        _static(
            camera,
            "window-reflection",
            (reflection_column, far_walk - 30.0),
            rng.uniform(0.7, 0.95),
            on_frames=rng.uniform(30.0, 80.0),
            off_frames=rng.uniform(60.0, 150.0),
        ),
    )
    return camera.config(
        f"street-{seed}",
        burn_in_frames=200,
        birth_rate=rng.uniform(0.06, 0.08),
        zones=zones,
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.2, 0.4),
        max_box_size=(180.0, 120.0),
    )


def plaza_edges(seed: int) -> SceneConfig:
    """An open plaza entered along whole edges, 768x576 at 15 frames/s, pedestrians only.

    Tests **entries spread along edges**: people enter anywhere along the left, bottom and
    right image edges and along a walkway at the far side (uniform segments 420-680 pixels
    long), heading into the plaza with a wide spread of directions (lateral speed spread half
    the walking speed). Four Gaussian blobs cannot fit a segment; a learner that places few
    components concentrates births where none occur. Clutter is mostly uniform (0.8-1.2 per
    frame) with a fountain patch (0.2-0.4) and a bench (0.2). About 24-36 births per half.

    Args:
        seed: draws the layout (edge weights, speeds, patch positions, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("plaza-edges", seed)
    camera = Camera(768, 576, 15.0, horizon_row=-400.0, height_per_row=0.09)
    zones = []
    for name, centre, extent, heading in (
        ("west-edge", (8.0, 340.0), (0.0, 210.0), (1.0, 0.0)),
        ("east-edge", (760.0, 340.0), (0.0, 210.0), (-1.0, 0.0)),
        ("south-edge", (384.0, 560.0), (340.0, 0.0), (0.0, -1.0)),
        ("north-walkway", (384.0, 110.0), (300.0, 0.0), (0.0, 1.0)),
    ):
        speed = camera.speed(centre[1], rng.uniform(*WALKING_SPEED))
        along, across = 0.2 * speed, 0.5 * speed
        zones.append(
            EntryZone(
                name,
                centre,
                (3.0, 3.0),
                (heading[0] * speed, heading[1] * speed),
                (along, across) if heading[0] else (across, along),
                weight=rng.uniform(0.5, 1.5),
                extent=extent,
            )
        )
    sources = (
        _patch(
            camera,
            "fountain",
            (rng.uniform(250.0, 520.0), rng.uniform(280.0, 380.0)),
            (rng.uniform(30.0, 50.0), rng.uniform(10.0, 20.0)),
            rng.uniform(0.2, 0.4),
        ),
        _static(camera, "bench", (rng.uniform(100.0, 670.0), rng.uniform(400.0, 480.0)), 0.2),
    )
    return camera.config(
        f"plaza-edges-{seed}",
        burn_in_frames=200,
        birth_rate=rng.uniform(0.08, 0.12),
        zones=tuple(zones),
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.8, 1.2),
        max_box_size=(64.0, 150.0),
    )


#: Expected births per frame of ``sparse-door``: 15 in a 300-frame training half.
SPARSE_BIRTH_RATE = 0.05
#: Births of ``sparse-door``'s training half (inclusive range), see :data:`CONDITIONS`.
SPARSE_TRAINING_BIRTHS = (10, 20)


def sparse_door(seed: int) -> SceneConfig:
    """A quiet corridor with two doors, 640x480 at 7 frames/s: few births.

    Tests **sparse births**: 15 births expected in the training half, and the scene is
    conditioned on 10-20 of them (:data:`CONDITIONS`), from an office door and a lift (both
    exits too) and the open end of the corridor (a segment on the left edge). A learner has
    a handful of events per zone; it must neither invent zones nor starve a zone it saw twice.
    Clutter is static and localised: a screen (0.2-0.4 per frame), a potted plant (a patch,
    0.2-0.4) and weak uniform clutter (0.05-0.15).

    Args:
        seed: draws the layout (door positions, speeds, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("sparse-door", seed)
    camera = Camera(640, 480, 7.0, horizon_row=-350.0, height_per_row=0.12)
    wall = rng.uniform(180.0, 220.0)
    office, lift = rng.uniform(120.0, 300.0), rng.uniform(360.0, 540.0)
    zones = (
        *_door(camera, rng, "office", office, wall, 0.35),
        *_door(camera, rng, "lift", lift, wall, 0.25),
        *_edge_walkers(camera, rng, rng.uniform(300.0, 360.0), 40.0, 0.2)[:1],
    )
    sources = (
        _static(camera, "screen", (rng.uniform(60.0, 580.0), wall - 20.0), rng.uniform(0.2, 0.4)),
        _patch(
            camera,
            "plant",
            (rng.uniform(60.0, 580.0), rng.uniform(330.0, 400.0)),
            (10.0, 8.0),
            rng.uniform(0.2, 0.4),
        ),
    )
    return camera.config(
        f"sparse-door-{seed}",
        burn_in_frames=100,
        birth_rate=SPARSE_BIRTH_RATE,
        zones=zones,
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.05, 0.15),
        max_box_size=(64.0, 150.0),
    )


def layout_change(seed: int) -> SceneConfig:
    """A station forecourt whose layout changes at the half, 768x576 at 10 frames/s.

    Tests **a test half unlike the training half**: people enter along the left edge and the
    bottom edge throughout; a side door is used only in the first half (it is locked at
    frame 300) and a gate on the right opens at frame 301 and takes the largest share of
    the births after it (weight 0.35 of 1). Context learned on the first half puts birth
    mass at the door and none at the gate. Clutter: two static patches (0.3-0.5 each) and
    uniform clutter (0.2-0.4), the same in both halves.

    Args:
        seed: draws the layout (door and gate positions, speeds, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("layout-change", seed)
    camera = Camera(768, 576, 10.0, horizon_row=-200.0, height_per_row=0.13)
    half = NUM_FRAMES // 2
    burn_in = 200
    door_row, gate_row = rng.uniform(160.0, 220.0), rng.uniform(260.0, 380.0)
    door = _door(camera, rng, "side-door", rng.uniform(200.0, 560.0), door_row, 0.25)
    gate_speed = camera.speed(gate_row, rng.uniform(*WALKING_SPEED))
    zones = (
        *_edge_walkers(camera, rng, rng.uniform(330.0, 430.0), 60.0, 0.15)[:1],
        EntryZone(
            "south-edge",
            (384.0, 566.0),
            (3.0, 3.0),
            (0.0, -camera.speed(520.0, rng.uniform(*WALKING_SPEED))),
            (1.0, 0.5),
            weight=0.25,
            extent=(300.0, 0.0),
        ),
        *(dataclasses.replace(zone, active_frames=(1 - burn_in, half)) for zone in door),
        EntryZone(
            "gate",
            (758.0, gate_row),
            (3.0, 12.0),
            (-gate_speed, 0.0),
            (0.25 * gate_speed, 0.2 * gate_speed),
            weight=0.35,
            active_frames=(half + 1, NUM_FRAMES),
        ),
    )
    sources = tuple(
        _patch(
            camera,
            name,
            (rng.uniform(80.0, 690.0), rng.uniform(200.0, 480.0)),
            (rng.uniform(20.0, 40.0), rng.uniform(10.0, 20.0)),
            rng.uniform(0.3, 0.5),
        )
        for name in ("shrub-a", "shrub-b")
    )
    return camera.config(
        f"layout-change-{seed}",
        burn_in_frames=burn_in,
        birth_rate=rng.uniform(0.08, 0.12),
        zones=zones,
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.2, 0.4),
        max_box_size=(64.0, 150.0),
    )


def flicker(seed: int) -> SceneConfig:
    """A shop front at dusk, 720x480 at 25 frames/s: clutter that comes and goes.

    Tests **flickering clutter**: three static sources switch on and off (a window reflection:
    on 40-80 frames, off 80-160; a blinking sign: on and off 8-15 frames each; a screen
    inside the shop: on 100-200, off 100-200), each firing 0.7-0.95 times per frame while on,
    beside one steady source (0.2-0.4) and weak uniform clutter (0.05-0.15). Learned clutter
    averages a source over the training half; a tracker then over-trusts a detection where a
    source is off and under-weights it where a source was off while learning. Pedestrians
    walk along the sidewalk from both edges and in and out of the shop door.

    Args:
        seed: draws the layout (positions, periods, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("flicker", seed)
    camera = Camera(720, 480, 25.0, horizon_row=-300.0, height_per_row=0.11)
    walk = rng.uniform(300.0, 380.0)
    facade = walk - 70.0
    door = rng.uniform(150.0, 570.0)
    zones = (
        *_door(camera, rng, "shop-door", door, facade + 10.0, 0.3),
        *_edge_walkers(camera, rng, walk, 40.0, 0.35),
    )
    columns = rng.permutation(np.linspace(90.0, 630.0, 4) + rng.uniform(-30.0, 30.0, 4))
    sources = (
        _static(
            camera,
            "window-reflection",
            (columns[0], facade - 20.0),
            rng.uniform(0.7, 0.95),
            on_frames=rng.uniform(40.0, 80.0),
            off_frames=rng.uniform(80.0, 160.0),
        ),
        _static(
            camera,
            "blinking-sign",
            (columns[1], facade - 40.0),
            rng.uniform(0.7, 0.95),
            on_frames=rng.uniform(8.0, 15.0),
            off_frames=rng.uniform(8.0, 15.0),
        ),
        _static(
            camera,
            "shop-screen",
            (columns[2], facade - 10.0),
            rng.uniform(0.7, 0.95),
            on_frames=rng.uniform(100.0, 200.0),
            off_frames=rng.uniform(100.0, 200.0),
        ),
        _static(camera, "bollard", (columns[3], walk + 60.0), rng.uniform(0.2, 0.4)),
    )
    return camera.config(
        f"flicker-{seed}",
        burn_in_frames=200,
        birth_rate=rng.uniform(0.04, 0.06),
        zones=zones,
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.05, 0.15),
        max_box_size=(64.0, 150.0),
    )


def uniform(seed: int) -> SceneConfig:
    """No useful context, 768x576 at 10 frames/s: births and clutter uniform over the image.

    Tests **that learned context does no harm where there is none**: every birth appears
    anywhere in rows 40-560 and columns 20-748 (people stepping out of occlusion, a camera
    that sees the middle of a crowd), moving in any direction (zero mean velocity, spread of
    a walking speed); all clutter is uniform (1-2 per frame). A learner should return
    (nearly) uniform intensities, and GM should match UM.

    Args:
        seed: draws the rates and speeds.

    Returns:
        The scene configuration.
    """
    rng = layout_rng("uniform", seed)
    camera = Camera(768, 576, 10.0, horizon_row=-150.0, height_per_row=0.16)
    speed = camera.speed(300.0, rng.uniform(*WALKING_SPEED))
    zone = EntryZone(
        "anywhere",
        (384.0, 300.0),
        (3.0, 3.0),
        (0.0, 0.0),
        (speed / np.sqrt(2.0), 0.6 * speed / np.sqrt(2.0)),
        extent=(364.0, 260.0),
    )
    return camera.config(
        f"uniform-{seed}",
        burn_in_frames=200,
        birth_rate=rng.uniform(0.08, 0.12),
        zones=(zone,),
        clutter_sources=(),
        uniform_clutter_rate=rng.uniform(1.0, 2.0),
        max_box_size=(64.0, 150.0),
    )


def misplaced(seed: int) -> SceneConfig:
    """A pedestrian square seen by a real detector, 768x576 at 7 frames/s (like PETS09-S2L1).

    Tests **a detector that places boxes of people badly**: 6-12 % of the detections of a
    person are a part of the person, a box shifted sideways or a box spilling over a
    neighbour (:func:`~jaxtrack.datasets.synthetic.badly_placed_boxes`), and 6-12 % of the
    detected people get a second such box. The IoU-0.5 evaluation counts these as false
    positives although the people produced them, so they lie where people walk, not where
    the scene's clutter sources are. People enter along both side edges (two walkways) and
    through a door; clutter is two static sources (a sign and a lamp post, 0.2-0.4 per frame
    each) and weak uniform clutter (0.05-0.15). A learner that takes every unmatched
    detection for clutter puts clutter on the walkways.

    Args:
        seed: draws the layout (walkway rows, door, source positions, rates).

    Returns:
        The scene configuration.
    """
    rng = layout_rng("misplaced", seed)
    camera = Camera(768, 576, 7.0, horizon_row=-350.0, height_per_row=0.13)
    upper, lower = rng.uniform(220.0, 300.0), rng.uniform(380.0, 460.0)
    zones = (
        *_edge_walkers(camera, rng, upper, 40.0, 0.3),
        *_edge_walkers(camera, rng, lower, 40.0, 0.3),
        *_door(camera, rng, "door", rng.uniform(150.0, 620.0), rng.uniform(160.0, 200.0), 0.4),
    )
    sources = (
        _static(
            camera,
            "sign",
            (rng.uniform(60.0, 700.0), rng.uniform(120.0, 180.0)),
            rng.uniform(0.2, 0.4),
        ),
        _static(
            camera,
            "lamp-post",
            (rng.uniform(60.0, 700.0), rng.uniform(300.0, 360.0)),
            rng.uniform(0.2, 0.4),
        ),
    )
    return camera.config(
        f"misplaced-{seed}",
        burn_in_frames=100,
        birth_rate=rng.uniform(0.1, 0.14),
        zones=zones,
        clutter_sources=sources,
        uniform_clutter_rate=rng.uniform(0.05, 0.15),
        max_box_size=(64.0, 150.0),
        misplaced_detection_prob=rng.uniform(0.06, 0.12),
        extra_detection_prob=rng.uniform(0.06, 0.12),
    )


#: The families, by name: each ``(seed) -> SceneConfig``.
FAMILIES: dict[str, Callable[[int], SceneConfig]] = {
    "street": street,
    "plaza-edges": plaza_edges,
    "sparse-door": sparse_door,
    "layout-change": layout_change,
    "flicker": flicker,
    "uniform": uniform,
    "misplaced": misplaced,
}


def _sparse_training_births(scene: SyntheticScene) -> bool:
    """Whether the training half holds :data:`SPARSE_TRAINING_BIRTHS` births."""
    low, high = SPARSE_TRAINING_BIRTHS
    births = int(np.sum(scene.birth_frames <= scene.config.num_frames // 2))
    return low <= births <= high


#: What a family's scene must show, checked on its generated truth: a scene that fails is
#: drawn again from the next simulation seed (:func:`generate_family_scene`), so the family is
#: its model conditioned on the event. Only ``sparse-door`` has one (10-20 training births).
CONDITIONS: dict[str, Callable[[SyntheticScene], bool]] = {
    "sparse-door": _sparse_training_births,
}
#: Most simulation seeds tried for a conditioned family.
MAX_ATTEMPTS = 100


def simulation_seed(seed: int, attempt: int) -> int:
    """The seed of a family's ``attempt``-th simulation: ``seed`` first, then derived ones.

    Args:
        seed: the scene's seed.
        attempt: 0, 1, ...

    Returns:
        ``seed`` for attempt 0, else a 32-bit seed drawn from ``SeedSequence([seed, attempt])``.
    """
    if attempt == 0:
        return seed
    return int(np.random.SeedSequence([seed, attempt]).generate_state(1)[0])


def family_config(family: str, seed: int) -> SceneConfig:
    """The configuration of a family's scene for ``seed`` (named ``<family>-<seed>``).

    Raises:
        InputError: an unknown family or a negative seed.
    """
    if family not in FAMILIES:
        raise InputError(f"unknown scene family {family!r}; known: {', '.join(FAMILIES)}")
    if seed < 0:
        raise InputError(f"seed must be >= 0, got {seed}")
    return FAMILIES[family](seed)


def generate_family_scene(
    family: str, seed: int, config: SceneConfig | None = None
) -> SyntheticScene:
    """Simulates a family's scene: its layout and its sequence both from ``seed``.

    The sequence is simulated from ``seed``; for a family with a condition
    (:data:`CONDITIONS`) that the sequence does not meet, from the next
    :func:`simulation_seed` until one does (the scene's ``seed`` says which).

    Args:
        family: a key of :data:`FAMILIES`.
        seed: the scene's seed (>= 0).
        config: the configuration simulated; default ``family_config(family, seed)`` (pass
            an edited one, e.g. fewer frames, to keep the family's condition).

    Returns:
        The scene.

    Raises:
        InputError: an unknown family, a negative seed, or no scene meeting the family's
            condition within :data:`MAX_ATTEMPTS` simulations.
    """
    config = config or family_config(family, seed)
    condition = CONDITIONS.get(family)
    for attempt in range(MAX_ATTEMPTS):
        scene = generate_scene(simulation_seed(seed, attempt), config)
        if condition is None or condition(scene):
            return scene
    raise InputError(
        f"scene family {family!r}: no simulation of seed {seed} in {MAX_ATTEMPTS} met its "
        f"condition ({condition.__doc__})"
    )


def write_family_scene(family: str, seed: int, out_dir: str | Path) -> Path:
    """Writes a family's scene as a MOTChallenge folder with its true context.

    The same files as ``jaxtrack simulate --family FAMILY --seed SEED --out DIR`` (which also
    draws ``preview.png``); see :func:`jaxtrack.datasets.synthetic.write_scene`.

    Returns:
        The folder.

    Raises:
        InputError: an unknown family or a negative seed.
    """
    return write_scene(generate_family_scene(family, seed), out_dir)
