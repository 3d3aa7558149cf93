"""Who walks where and when in a video scene: background walkers and scripted hard cases.

:func:`draw_people` draws, with the scene's random generator, every person of a
:class:`~jaxtrack.datasets.video_config.VideoSceneConfig` as a :class:`Person` (entry frame,
foot points frame by frame, zones, clothes); :mod:`jaxtrack.datasets.video_scene` turns them
into the ground truth, events and detections.

**People.** Everybody enters through a zone (foot point normal about the zone's centre with
a sixth of its size as standard deviation, clipped to its box; a group at the centre) and
walks a piecewise-linear route (:func:`~jaxtrack.datasets.video_paths.walk`: perspective
speed, gait) to a point in another zone, where they leave. Routes never walk through the
occluder's base (:func:`~jaxtrack.datasets.video_paths.crosses_occluder`; a route that would is
drawn again). Each person walks at an own pace ``U(0.85, 1.15) walking_pace`` (a group at
one pace) and wears two colours from a clothing palette, top and bottom (plus a uniform
per-channel change of up to +-15 levels). Nobody enters before frame ``FIRST_ENTRY``.

**Scripted hard cases** (placed by the seed; the events of
:attr:`~jaxtrack.datasets.video_scene.VideoScene.events`):

* ``crossing``: two similarly dressed people (the same palette colours, within +-4 levels;
  with ``crossing_alike`` ``"top"`` or ``"bottom"`` only that half alike, the other half of
  the second person another palette colour) from different zones to different zones pass
  the same point in the same frame, one ``CROSSING_OFFSET`` body heights nearer the camera;
  the event's frames are the first and last in which their boxes overlap;
* ``group``: ``GROUP_SIZE`` people enter together side by side (``GROUP_SPACING`` body heights
  apart, across the walking direction), walk to a split point and leave through different
  zones; frames: entry to split;
* ``occlusion``: a person walks along the row just behind the occluder, from one side to the
  other; frames: those in which the box lies wholly inside the occluder (visibility 0);
* ``standing``: a person walks to a point and stands still for ``stand_frames`` frames
  (legs together); frames: those at the standing point;
* ``entry`` / ``exit``: one per person and zone (the exit only when it happens within the
  scene).

Background walkers (``walkers_per_zone`` per zone) enter at times spread evenly over the
scene (one in each of ``walkers_per_zone`` equal slots of ``FIRST_ENTRY..T - EXIT_MARGIN``),
and leave through a random other zone via a waypoint near the route's midpoint.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxtrack.datasets.video_config import VideoSceneConfig
from jaxtrack.datasets.video_paths import crosses_occluder, nominal_height, person_boxes, walk
from jaxtrack.errors import InputError

#: First frame in which anybody enters.
FIRST_ENTRY = 10
#: Background walkers enter no later than this many frames before the end.
EXIT_MARGIN = 60
#: People in the scripted group.
GROUP_SIZE = 3
#: Distance between group neighbours, body heights.
GROUP_SPACING = 0.35
#: The second person of the crossing passes this many body heights nearer the camera.
CROSSING_OFFSET = 0.12
#: Frames after a scripted moment that the scene must still show (a group's split needs more).
EVENT_MARGIN = 10
SPLIT_MARGIN = 80
#: Standard deviation of an entry or exit point about its zone's centre, in zone sizes.
ZONE_SPREAD = 1 / 6
#: Draws of a route that avoids the occluder (or of a ground point clear of it) before the
#: layout is refused.
MAX_ROUTE_TRIES = 200
#: Clothing palette (RGB).
CLOTHING = np.array(
    [
        (30, 40, 90),
        (180, 30, 35),
        (225, 225, 215),
        (35, 35, 38),
        (120, 120, 125),
        (40, 110, 50),
        (220, 190, 40),
        (110, 70, 40),
        (100, 160, 215),
        (110, 50, 130),
        (230, 120, 30),
        (200, 180, 140),
    ]
)
#: Per-channel colour change of an ordinary person, and of the crossing's similar pair.
COLOUR_JITTER = 15
SIMILAR_JITTER = 4


@dataclasses.dataclass
class Person:
    """A person of the script, before ids are given.

    Attributes:
        start: frame of the first foot point (the entry).
        feet: ``[n, 2]`` foot points, one per frame from ``start`` on (the walk may run past
            the scene's last frame).
        role: ``"walker"``, ``"crossing"``, ``"group"``, ``"occlusion"`` or ``"standing"``.
        entry_zone: index of the entry zone.
        exit_zone: index of the exit zone.
        top: RGB of the upper body.
        bottom: RGB of the legs.
        marks: the frames of the person's scripted moments (``"split"`` of a group member,
            ``"stand"`` ``(first, last)`` of the standing person) and ``"needed"``, the frames
            the scene must have for them to be seen.
    """

    start: int
    feet: np.ndarray
    role: str
    entry_zone: int
    exit_zone: int
    top: np.ndarray
    bottom: np.ndarray
    marks: dict = dataclasses.field(default_factory=dict)


def draw_people(config: VideoSceneConfig, rng: np.random.Generator) -> list[Person]:
    """Everybody of a scene, the scripted people first (see the module docstring).

    Args:
        config: the scene.
        rng: the scene's random generator (advanced).

    Returns:
        The people, in the order drawn.

    Raises:
        InputError: ``num_frames`` too short for the scripted events (the message gives the
            number needed), or a layout in which no route avoids the occluder.
    """
    return _Script(config, rng).people()


class _Script:
    """Draws the people of a scene: the scripted hard cases and the background walkers."""

    def __init__(self, config: VideoSceneConfig, rng: np.random.Generator):
        self.config = config
        self.rng = rng
        self.zones = np.array([config.pixels(zone.box) for zone in config.zones])
        self.centres = self.zones[:, :2] + self.zones[:, 2:] / 2
        width, height = config.image_width, config.image_height
        self.ground = np.array([0.05 * width, (config.ground_row + 0.05) * height])
        self.ground_end = np.array([0.95 * width, 0.95 * height])

    def people(self) -> list[Person]:
        """Everybody, scripted people first; refuses a scene too short for their events."""
        people = [
            *self._crossing(),
            *self._group(),
            self._occlusion(),
            self._standing(),
            *self._walkers(),
        ]
        needed = max(person.marks.get("needed", 0) for person in people)
        if needed > self.config.num_frames:
            raise InputError(
                f"num_frames {self.config.num_frames} is too short for the scripted events of "
                f"this seed and layout: at least {needed} frames are needed"
            )
        return people

    # -- drawing helpers ------------------------------------------------------------------

    def _pace(self) -> float:
        return self.config.walking_pace * self.rng.uniform(0.85, 1.15)

    def _zone_point(self, zone: int) -> np.ndarray:
        """A foot point in a zone: normal about its centre, ``ZONE_SPREAD`` of its size as
        standard deviation, clipped to its box (people keep to the middle of a path)."""
        x, y, w, h = self.zones[zone]
        point = self.centres[zone] + self.rng.normal(0, ZONE_SPREAD, 2) * [w, h]
        return np.clip(point, [x, y], [x + w, y + h])

    def _other_zone(self, zone: int) -> int:
        return int(self.rng.choice([z for z in range(len(self.zones)) if z != zone]))

    def _jitter(self, colour: np.ndarray, amount: int) -> np.ndarray:
        return np.clip(colour + self.rng.integers(-amount, amount + 1, 3), 0, 255)

    def _clothes(self) -> tuple[np.ndarray, np.ndarray]:
        top, bottom = self.rng.choice(len(CLOTHING), 2, replace=False)
        return (
            self._jitter(CLOTHING[top], COLOUR_JITTER),
            self._jitter(CLOTHING[bottom], COLOUR_JITTER),
        )

    def _ground_point(self, lower, upper, accept=None) -> np.ndarray:
        """A point uniform over a part of the ground, clear of the occluder (and accepted).

        Args:
            lower, upper: corners of the part, fractions of the ground's extent.
            accept: an extra condition on the point, or None.

        Raises:
            InputError: no such point in ``MAX_ROUTE_TRIES`` draws (the layout leaves no room).
        """
        span = self.ground_end - self.ground
        for _ in range(MAX_ROUTE_TRIES):
            point = self.ground + span * self.rng.uniform(lower, upper)
            if self._clear_of_occluder(point) and (accept is None or accept(point)):
                return point
        raise InputError(
            f"no point of the ground between {lower} and {upper} (fractions of it) is clear of "
            f"the occluder {self.config.occluder} and fits the scripted event after "
            f"{MAX_ROUTE_TRIES} tries; move the occluder or the zones"
        )

    def _clear_of_occluder(self, point: np.ndarray) -> bool:
        """Whether a person standing on ``point`` is a body width or more from the occluder."""
        height = 1.2 * float(nominal_height(point[1], self.config))
        x, y, w, h = person_boxes(point[None], np.array([height]), self.config.aspect_ratio)[0]
        ox, oy, ow, oh = self.config.pixels(self.config.occluder)
        return x > ox + ow + w or x + 2 * w < ox or y > oy + oh or y + h < oy

    def _routes(self, draw) -> list[np.ndarray]:
        """``draw()`` (a list of routes) drawn again until no route crosses the occluder."""
        for _ in range(MAX_ROUTE_TRIES):
            routes = draw()
            if not any(crosses_occluder(route, self.config) for route in routes):
                return routes
        raise InputError(
            f"no route between the zones avoids the occluder {self.config.occluder} after "
            f"{MAX_ROUTE_TRIES} tries; move the occluder or the zones"
        )

    # -- background walkers -----------------------------------------------------------------

    def _walkers(self) -> list[Person]:
        """``walkers_per_zone`` per zone, one entering in each of as many equal time slots."""
        config = self.config
        count = config.walkers_per_zone
        last = max(config.num_frames - EXIT_MARGIN, FIRST_ENTRY + 1)
        slot = (last - FIRST_ENTRY) / max(count, 1)
        spread = (self.ground_end - self.ground) * [0.08, 0.06]
        people = []
        for zone in range(len(self.zones)):
            for k in range(count):
                start = FIRST_ENTRY + int((k + self.rng.uniform()) * slot)
                exit_ = self._other_zone(zone)

                def draw(zone=zone, exit_=exit_):
                    entry, end = self._zone_point(zone), self._zone_point(exit_)
                    middle = (entry + end) / 2 + self.rng.normal(0, 1, 2) * spread
                    middle = np.clip(middle, self.ground, self.ground_end)
                    return [np.stack([entry, middle, end])]

                (route,) = self._routes(draw)
                feet, _ = walk(route, self._pace(), config)
                people.append(Person(start, feet, "walker", zone, exit_, *self._clothes()))
        return people

    # -- scripted hard cases ------------------------------------------------------------------

    def _crossing(self) -> list[Person]:
        """Two similarly dressed people from different zones reach one point in one frame
        (their clothes alike as ``crossing_alike`` says)."""
        config = self.config
        zone_a = int(self.rng.integers(len(self.zones)))
        zone_b = self._other_zone(zone_a)
        exit_a = self._other_zone(zone_a)
        exit_b = int(
            self.rng.choice([z for z in range(len(self.zones)) if z not in (zone_b, exit_a)])
        )

        def draw():
            point = self._ground_point((0.2, 0.35), (0.6, 0.75))
            offset = CROSSING_OFFSET * float(nominal_height(point[1], config))
            nearer = point + np.array([0.0, offset])
            return [
                np.stack([self._zone_point(zone_a), point, self._zone_point(exit_a)]),
                np.stack([self._zone_point(zone_b), nearer, self._zone_point(exit_b)]),
            ]

        routes = self._routes(draw)
        walks = [walk(route, self._pace(), config) for route in routes]
        meet = max(arrivals[1] for _, arrivals in walks) + FIRST_ENTRY
        meet += int(self.rng.integers(0, 80))
        top, bottom = self.rng.choice(len(CLOTHING), 2, replace=False)
        clothes = [(top, bottom), (top, bottom)]
        if config.crossing_alike != "both":
            # The second person's other half: a palette colour neither of the pair wears.
            other = int(
                self.rng.choice([c for c in range(len(CLOTHING)) if c not in (top, bottom)])
            )
            clothes[1] = (top, other) if config.crossing_alike == "top" else (other, bottom)
        people = []
        for (feet, arrivals), entry, exit_, (top_, bottom_) in zip(
            walks, (zone_a, zone_b), (exit_a, exit_b), clothes, strict=True
        ):
            person = Person(
                int(meet - arrivals[1]),
                feet,
                "crossing",
                entry,
                exit_,
                self._jitter(CLOTHING[top_], SIMILAR_JITTER),
                self._jitter(CLOTHING[bottom_], SIMILAR_JITTER),
            )
            person.marks = {"needed": meet + EVENT_MARGIN}
            people.append(person)
        return people

    def _group(self) -> list[Person]:
        """``GROUP_SIZE`` people side by side from one zone to a split point, then apart."""
        config = self.config
        middle = (self.ground + self.ground_end) / 2
        fits = [z for z in range(len(self.zones)) if self._formation_fits(z, middle)]
        if not fits:
            raise InputError(
                f"no zone is wide enough for a group of {GROUP_SIZE} walking side by side "
                f"({GROUP_SPACING} body heights apart); widen a zone"
            )
        zone = int(self.rng.choice(fits))
        others = self.rng.permutation([z for z in range(len(self.zones)) if z != zone])
        exits = [int(others[k % len(others)]) for k in range(GROUP_SIZE)]
        pace = self._pace()

        def draw():
            split = self._ground_point(
                (0.3, 0.3), (0.7, 0.7), lambda point: self._formation_fits(zone, point)
            )
            leader, _ = walk(np.stack([self.centres[zone], split]), pace, config)
            offsets = self._formation(split - self.centres[zone])
            height = nominal_height(leader[:, 1], config)[None, :, None]
            together = leader[None] + offsets[:, None] * height  # [GROUP_SIZE, n, 2]
            ends = [self._zone_point(exit_) for exit_ in exits]
            routes = [np.stack([path[-1], end]) for path, end in zip(together, ends, strict=True)]
            return [*routes, *together]

        routes = self._routes(draw)
        start = FIRST_ENTRY + 20 + int(self.rng.integers(0, 80))
        people = []
        for k in range(GROUP_SIZE):
            together = routes[GROUP_SIZE + k]
            apart, _ = walk(routes[k], pace, config)
            person = Person(
                start,
                np.concatenate([together, apart[1:]]),
                "group",
                zone,
                exits[k],
                *self._clothes(),
            )
            split = start + len(together) - 1
            person.marks = {"split": split, "needed": split + SPLIT_MARGIN}
            people.append(person)
        return people

    def _formation(self, direction: np.ndarray) -> np.ndarray:
        """Members' offsets across ``direction``, body heights, ``[GROUP_SIZE, 2]``."""
        across = np.array([-direction[1], direction[0]]) / np.hypot(*direction)
        spread = (np.arange(GROUP_SIZE) - (GROUP_SIZE - 1) / 2) * GROUP_SPACING
        return spread[:, None] * across[None]

    def _formation_fits(self, zone: int, target: np.ndarray) -> bool:
        """Whether a group entering at the zone's centre, heading for ``target``, has every
        member's foot point inside the zone."""
        x, y, w, h = self.zones[zone]
        centre = self.centres[zone]
        height = float(nominal_height(centre[1], self.config))
        feet = centre + self._formation(target - centre) * height
        return bool(np.all((feet >= [x, y]) & (feet <= [x + w, y + h])))

    def _occlusion(self) -> Person:
        """A person walking along the row just behind the occluder, across its whole width."""
        config = self.config
        ox, oy, ow, oh = config.pixels(config.occluder)
        row = oy + 0.95 * oh
        width = config.image_width
        left = np.array([max(ox - 0.5 * ow, 0.02 * width), row])
        right = np.array([min(ox + 1.5 * ow, 0.98 * width), row])
        to_left = np.hypot(*(self.centres - left).T)
        to_right = np.hypot(*(self.centres - right).T)
        entry = int(np.argmin(to_left))
        to_right[entry] = np.inf
        exit_ = int(np.argmin(to_right))
        passage = [left, right]
        if self.rng.uniform() < 0.5:
            entry, exit_, passage = exit_, entry, passage[::-1]

        def draw():
            return [np.stack([self._zone_point(entry), *passage, self._zone_point(exit_)])]

        (route,) = self._routes(draw)
        feet, arrivals = walk(route, self._pace(), config)
        start = FIRST_ENTRY + int(self.rng.integers(0, 60))
        person = Person(start, feet, "occlusion", entry, exit_, *self._clothes())
        person.marks = {"needed": start + int(arrivals[2]) + EVENT_MARGIN}
        return person

    def _standing(self) -> Person:
        """A person who walks to a point, stands still for ``stand_frames``, and walks on."""
        config = self.config
        entry = int(self.rng.integers(len(self.zones)))
        exit_ = self._other_zone(entry)

        def draw():
            point = self._ground_point((0.1, 0.3), (0.6, 0.85))
            return [np.stack([self._zone_point(entry), point, self._zone_point(exit_)])]

        (route,) = self._routes(draw)
        feet, arrivals = walk(route, self._pace(), config, {1: config.stand_frames})
        start = FIRST_ENTRY + int(self.rng.integers(0, 60))
        person = Person(start, feet, "standing", entry, exit_, *self._clothes())
        first = start + int(arrivals[1])
        person.marks = {
            "stand": (first, first + config.stand_frames - 1),
            "needed": first + config.stand_frames + EVENT_MARGIN,
        }
        return person
