"""A scripted surveillance video scene: people walking between entry/exit zones, hard cases.

:func:`generate_video_scene` draws, from a seed, the script of a
:class:`~jaxtrack.datasets.video_config.VideoSceneConfig`: who walks where and when, the
ground truth (boxes, MOT16/17 visibility), detections for ``det.txt``, the true appearance of
each person and the scripted events. :mod:`jaxtrack.datasets.render` draws its frames and
:mod:`jaxtrack.datasets.video_files` writes it as a MOTChallenge folder with ``<name>.mp4``.

**People** come from :func:`~jaxtrack.datasets.video_script.draw_people` (routes, timing, clothes
and the scripted hard cases; see there). Each then gets an own height scale
``s ~ N(1, height_spread)`` (clipped to ``HEIGHT_SPREAD_CLIP`` spreads), a gait phase offset
and a skin tone.

**Ground truth** (MOT16/17 layout, ``frame, id, x, y, w, h, 1, 1, visibility``): the boxes of
:func:`~jaxtrack.datasets.video_paths.person_boxes`, ids ``1..N`` in order of entry, class 1
(pedestrian), visibility from :func:`~jaxtrack.datasets.video_paths.box_visibility` (the
occluder, nearer people and the image border).

**Detections** (``det.txt``): a person with visibility ``v`` is detected with probability
``detection_prob * clip((v - 0.2) / 0.3, 0, 1)``; a detection of box ``(cx, cy, w, h)`` is
``N((cx, cy, w, h), diag(s_w w, s_h h, s_w w, s_h h)^2)``. False detections: ``Poisson
(clutter_rate)`` per frame of nominal person size with a foot point uniform over the ground,
and, in gust frames (the vegetation moves, :attr:`VideoScene.gust`),
``Poisson(vegetation_clutter_rate)`` boxes inside the vegetation region (a fifth to a half of
its size). Scores ``Beta(6, 1.5)`` (true) and ``Beta(3, 3)`` (false); detection boxes are
clipped to the image; both tables are rounded to 1/1000 pixel.

**Foliage and noise** (drawn here, used by the renderer): gusts are a two-state Markov chain
(mean gust ``GUST_FRAMES``, mean calm ``CALM_FRAMES`` frames); the foliage sways by an AR(1)
offset whose innovation is larger in gusts (:attr:`VideoScene.vegetation_offsets`); each frame
draws an offset into the pixel-noise field (:attr:`VideoScene.noise_offsets`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from jaxtrack.boxes import cxcywh_to_xywh, xywh_to_cxcywh
from jaxtrack.datasets.video_config import HEIGHT_SPREAD_CLIP, VideoSceneConfig
from jaxtrack.datasets.video_paths import (
    box_visibility,
    gait_phase,
    nominal_height,
    person_boxes,
)
from jaxtrack.datasets.video_script import draw_people
from jaxtrack.errors import InputError
from jaxtrack.io.motchallenge import MotTable, SequenceInfo

#: Skin tones (RGB) of the heads.
SKIN = np.array([(230, 190, 160), (200, 150, 110), (150, 100, 70), (95, 65, 45)])
#: Beta parameters of the scores of true and false detections.
TARGET_SCORE = (6.0, 1.5)
CLUTTER_SCORE = (3.0, 3.0)
#: Visibility below which a person is never detected, and above which detection is sure
#: (times ``detection_prob``).
UNSEEN, SEEN = 0.2, 0.5
#: Decimals kept in written boxes (pixels).
BOX_DECIMALS = 3
#: Vegetation sway: largest offset (fraction of the image width, at least 1 pixel), its AR(1)
#: persistence and per-frame innovation in calm and gust frames (units of the largest
#: offset), and the mean lengths of gusts and of calm spells, frames.
SWAY = 0.008
SWAY_PERSISTENCE = 0.75
SWAY_INNOVATION = (0.05, 0.6)
GUST_FRAMES, CALM_FRAMES = 12.0, 50.0
#: Range of the per-frame offsets into the pixel-noise field, pixels.
NOISE_OFFSETS = 64


@dataclasses.dataclass(frozen=True)
class ScriptedEvent:
    """One scripted event.

    Attributes:
        kind: ``"crossing"``, ``"group"``, ``"occlusion"``, ``"standing"``, ``"entry"`` or
            ``"exit"``.
        ids: the ground-truth ids involved.
        frames: ``(first, last)``, 1-based inclusive.
        zone: the zone's name (entry and exit events), else None.
    """

    kind: str
    ids: tuple[int, ...]
    frames: tuple[int, int]
    zone: str | None = None


@dataclasses.dataclass(frozen=True)
class Appearance:
    """The true appearance of each person (row ``i`` is ground-truth id ``i + 1``).

    Attributes:
        top: RGB of the upper body (torso and arms), ``[N, 3]`` uint8.
        bottom: RGB of the legs, ``[N, 3]`` uint8.
        skin: RGB of the head, ``[N, 3]`` uint8.
        height_scale: own height relative to the perspective law, ``[N]``.
    """

    top: np.ndarray
    bottom: np.ndarray
    skin: np.ndarray
    height_scale: np.ndarray


@dataclasses.dataclass(frozen=True)
class VideoScene:
    """A scripted scene with its truth; rows of ``gt_*`` arrays follow ``gt_table``.

    Attributes:
        seed: the seed it was drawn from (the renderer's textures use it too).
        config: the configuration.
        info: sequence information (``seqinfo.ini``).
        gt_table: ground truth, sorted by frame then id; ``extra`` = (class 1, visibility).
        det_table: detections, sorted by frame, shuffled within a frame.
        det_target_ids: ground-truth id of each detection, -1 for a false one.
        gt_phase: gait phase of each row, radians.
        gt_walking: whether the person moved into this row's position (False: standing).
        appearance: the true appearance of each person.
        roles: each person's part: ``"walker"``, ``"crossing"``, ``"group"``,
            ``"occlusion"`` or ``"standing"``.
        entry_zones: index into ``config.zones`` of each person's entry zone.
        exit_zones: index of each person's exit zone, -1 when still in view at the end.
        events: the scripted events.
        zones: ``(x, y, w, h)`` pixel box of each zone, ``[Z, 4]``.
        occluder: the occluder's pixel box ``[4]``.
        vegetation: the vegetation region's pixel box ``[4]``.
        gust: whether the vegetation is in a gust, per frame ``[T]``.
        vegetation_offsets: ``(dx, dy)`` sway of the foliage texture per frame, ``[T, 2]``
            integer pixels.
        noise_offsets: ``(dx, dy)`` offset into the pixel-noise field per frame, ``[T, 2]``.
    """

    seed: int
    config: VideoSceneConfig
    info: SequenceInfo
    gt_table: MotTable
    det_table: MotTable
    det_target_ids: np.ndarray
    gt_phase: np.ndarray
    gt_walking: np.ndarray
    appearance: Appearance
    roles: tuple[str, ...]
    entry_zones: np.ndarray
    exit_zones: np.ndarray
    events: tuple[ScriptedEvent, ...]
    zones: np.ndarray
    occluder: np.ndarray
    vegetation: np.ndarray
    gust: np.ndarray
    vegetation_offsets: np.ndarray
    noise_offsets: np.ndarray

    @property
    def visibility(self) -> np.ndarray:
        """Visible fraction of each ground-truth row (column 9 of ``gt.txt``)."""
        return self.gt_table.extra[:, 1]

    @property
    def num_people(self) -> int:
        return len(self.roles)

    def frame_rows(self, frame: int) -> np.ndarray:
        """Indices of the ground-truth rows of a 1-based frame."""
        frames = self.gt_table.frames
        return np.arange(
            np.searchsorted(frames, frame, "left"), np.searchsorted(frames, frame, "right")
        )

    def person_rows(self, person_id: int) -> np.ndarray:
        """Indices of the ground-truth rows of one person, in frame order."""
        return np.flatnonzero(self.gt_table.ids == person_id)


def generate_video_scene(seed: int, config: VideoSceneConfig | None = None) -> VideoScene:
    """Draws the script of a video scene (see the module docstring).

    Args:
        seed: non-negative integer; the same seed and config give the same scene (and frames).
        config: the configuration; default ``VideoSceneConfig()``.

    Returns:
        The scene.

    Raises:
        InputError: ``num_frames`` too short for the scripted events (the message gives the
            number needed), or a layout in which no route avoids the occluder.
    """
    config = config or VideoSceneConfig()
    rng = np.random.default_rng(seed)
    people = sorted(draw_people(config, rng), key=lambda person: person.start)
    spread = HEIGHT_SPREAD_CLIP * config.height_spread
    scales = np.clip(rng.normal(1.0, config.height_spread, len(people)), 1 - spread, 1 + spread)
    phases = rng.uniform(0, 2 * np.pi, len(people))
    gt_table, gt_phase, gt_walking = _ground_truth(people, scales, phases, config)
    gust = _gusts(config.num_frames, rng)
    det_table, det_ids = _detections(gt_table, gust, config, rng)
    last_frames = np.array([person.start + len(person.feet) - 1 for person in people])
    return VideoScene(
        seed=seed,
        config=config,
        info=SequenceInfo(
            name=config.name if config.name is not None else f"video-{seed}",
            seq_length=config.num_frames,
            im_width=config.image_width,
            im_height=config.image_height,
            frame_rate=config.frame_rate,
        ),
        gt_table=gt_table,
        det_table=det_table,
        det_target_ids=det_ids,
        gt_phase=gt_phase,
        gt_walking=gt_walking,
        appearance=Appearance(
            top=np.array([p.top for p in people], np.uint8).reshape(-1, 3),
            bottom=np.array([p.bottom for p in people], np.uint8).reshape(-1, 3),
            skin=SKIN[rng.integers(0, len(SKIN), len(people))].astype(np.uint8).reshape(-1, 3),
            height_scale=scales,
        ),
        roles=tuple(person.role for person in people),
        entry_zones=np.array([person.entry_zone for person in people], np.int64),
        exit_zones=np.where(
            last_frames <= config.num_frames, [person.exit_zone for person in people], -1
        ).astype(np.int64),
        events=_events(people, gt_table, config),
        zones=np.array([config.pixels(zone.box) for zone in config.zones]),
        occluder=np.array(config.pixels(config.occluder)),
        vegetation=np.array(config.pixels(config.vegetation)),
        gust=gust,
        vegetation_offsets=_sway(gust, max(1, round(SWAY * config.image_width)), rng),
        noise_offsets=rng.integers(0, NOISE_OFFSETS, (config.num_frames, 2)),
    )


def _ground_truth(people, scales, phases, config: VideoSceneConfig):
    """The gt table (boxes, class 1, visibility) and each row's gait phase and walking flag."""
    frames, ids, feet, heights, phase, walking = [], [], [], [], [], []
    for index, person in enumerate(people):
        count = min(len(person.feet), config.num_frames - person.start + 1)
        track = person.feet[:count]
        frames.append(person.start + np.arange(count))
        ids.append(np.full(count, index + 1))
        feet.append(track)
        heights.append(scales[index] * nominal_height(track[:, 1], config))
        phase.append(phases[index] + gait_phase(person.feet, config)[:count])
        moved = np.any(np.diff(person.feet, axis=0) != 0, axis=1)
        walking.append(np.concatenate([[True], moved])[:count])
    frames, ids = np.concatenate(frames), np.concatenate(ids)
    order = np.lexsort((ids, frames))
    frames, ids = frames[order], ids[order]
    boxes = person_boxes(np.concatenate(feet), np.concatenate(heights), config.aspect_ratio)
    boxes = boxes[order]
    visibility = np.zeros(len(frames))
    occluder = np.array(config.pixels(config.occluder))
    size = (config.image_width, config.image_height)
    bounds = np.flatnonzero(np.diff(frames)) + 1
    for rows in np.split(np.arange(len(frames)), bounds):
        visibility[rows] = box_visibility(boxes[rows], occluder, size)
    extra = np.stack([np.ones(len(frames)), visibility], axis=1)
    table = MotTable.from_arrays(frames, ids, np.round(boxes, BOX_DECIMALS) + 0.0, None, extra)
    return table, np.concatenate(phase)[order], np.concatenate(walking)[order]


def _events(people, gt: MotTable, config: VideoSceneConfig) -> tuple[ScriptedEvent, ...]:
    """The scripted events, from the people's marks and their ground truth."""
    names = [zone.name for zone in config.zones]
    events = []
    rows = {pid: np.flatnonzero(gt.ids == pid) for pid in range(1, len(people) + 1)}
    for pid, person in enumerate(people, start=1):
        first = person.start
        last = person.start + len(person.feet) - 1
        events.append(ScriptedEvent("entry", (pid,), (first, first), names[person.entry_zone]))
        if last <= config.num_frames:
            events.append(ScriptedEvent("exit", (pid,), (last, last), names[person.exit_zone]))
        if "stand" in person.marks:
            events.append(ScriptedEvent("standing", (pid,), person.marks["stand"]))
        if person.role == "occlusion":
            hidden = _inside(gt.boxes[rows[pid]], np.array(config.pixels(config.occluder)))
            frames = gt.frames[rows[pid]][hidden]
            if not frames.size:
                raise InputError(
                    f"the occluder {config.occluder} never wholly hides the person walking "
                    "behind it; make it larger"
                )
            events.append(ScriptedEvent("occlusion", (pid,), (int(frames[0]), int(frames[-1]))))
    group = [pid for pid, person in enumerate(people, start=1) if person.role == "group"]
    split = people[group[0] - 1].marks["split"]
    events.append(ScriptedEvent("group", tuple(group), (people[group[0] - 1].start, split)))
    pair = [pid for pid, person in enumerate(people, start=1) if person.role == "crossing"]
    overlap = _overlap_frames(gt, rows[pair[0]], rows[pair[1]])
    events.append(ScriptedEvent("crossing", tuple(pair), (int(overlap[0]), int(overlap[-1]))))
    return tuple(sorted(events, key=lambda event: (event.frames[0], event.kind, event.ids)))


def _inside(boxes: np.ndarray, outer: np.ndarray) -> np.ndarray:
    """Whether each ``(x, y, w, h)`` box lies wholly inside the box ``outer``."""
    return (
        (boxes[:, 0] >= outer[0])
        & (boxes[:, 1] >= outer[1])
        & (boxes[:, 0] + boxes[:, 2] <= outer[0] + outer[2])
        & (boxes[:, 1] + boxes[:, 3] <= outer[1] + outer[3])
    )


def _overlap_frames(gt: MotTable, rows_a: np.ndarray, rows_b: np.ndarray) -> np.ndarray:
    """Frames in which the boxes of two people overlap (a positive intersection area)."""
    common, index_a, index_b = np.intersect1d(
        gt.frames[rows_a], gt.frames[rows_b], return_indices=True
    )
    a, b = gt.boxes[rows_a[index_a]], gt.boxes[rows_b[index_b]]
    width = np.minimum(a[:, 0] + a[:, 2], b[:, 0] + b[:, 2]) - np.maximum(a[:, 0], b[:, 0])
    height = np.minimum(a[:, 1] + a[:, 3], b[:, 1] + b[:, 3]) - np.maximum(a[:, 1], b[:, 1])
    return common[(width > 0) & (height > 0)]


def _gusts(num_frames: int, rng: np.random.Generator) -> np.ndarray:
    """Gust frames: a two-state Markov chain (mean gust ``GUST_FRAMES``, mean calm
    ``CALM_FRAMES``) started from its stationary law."""
    gust = np.zeros(num_frames, bool)
    draws = rng.random(num_frames)
    state = draws[0] < GUST_FRAMES / (GUST_FRAMES + CALM_FRAMES)
    for t in range(num_frames):
        if t:
            state ^= draws[t] < (1 / GUST_FRAMES if state else 1 / CALM_FRAMES)
        gust[t] = state
    return gust


def _sway(gust: np.ndarray, largest: int, rng: np.random.Generator) -> np.ndarray:
    """Integer ``(dx, dy)`` sway of the foliage per frame: ``s_t = r s_{t-1} + q_t n_t``,
    ``n_t ~ N(0, I2)``, ``q_t`` the calm or gust innovation, offsets ``round(clip(s_t, -1, 1)
    largest)``."""
    innovation = np.where(gust, SWAY_INNOVATION[1], SWAY_INNOVATION[0])[:, None]
    noise = rng.normal(size=(gust.size, 2)) * innovation
    state = np.zeros(2)
    sway = np.zeros((gust.size, 2))
    for t in range(gust.size):
        state = SWAY_PERSISTENCE * state + noise[t]
        sway[t] = state
    return np.round(np.clip(sway, -1, 1) * largest).astype(np.int64)


def _detections(gt: MotTable, gust: np.ndarray, config: VideoSceneConfig, rng):
    """``det.txt`` rows (see the module docstring) and the gt id of each (-1: false)."""
    visibility = gt.extra[:, 1]
    ramp = np.clip((visibility - UNSEEN) / (SEEN - UNSEEN), 0.0, 1.0)
    found = rng.random(len(gt)) < config.detection_prob * ramp
    s_w, s_h = config.measurement_noise
    centres = xywh_to_cxcywh(gt.boxes[found])
    noise = rng.normal(size=centres.shape) * centres[:, [2, 3, 2, 3]] * [s_w, s_h, s_w, s_h]
    measured = centres + noise
    num_frames = config.num_frames
    uniform_counts = rng.poisson(config.clutter_rate, num_frames)
    foliage_counts = rng.poisson(config.vegetation_clutter_rate * gust)
    width, height = config.image_width, config.image_height
    feet = rng.uniform([0, config.ground_row * height], [width, height], (uniform_counts.sum(), 2))
    tall = nominal_height(feet[:, 1], config)
    uniform = np.stack([feet[:, 0], feet[:, 1] - tall / 2, config.aspect_ratio * tall, tall], 1)
    vx, vy, vw, vh = config.pixels(config.vegetation)
    sizes = rng.uniform(0.2, 0.5, (foliage_counts.sum(), 2)) * [vw, vh]
    corners = [vx, vy] + rng.uniform(0, 1, sizes.shape) * ([vw, vh] - sizes)
    foliage = np.concatenate([corners + sizes / 2, sizes], 1)
    boxes = np.concatenate([measured, uniform, foliage])
    frames = np.concatenate(
        [
            gt.frames[found],
            np.repeat(np.arange(1, num_frames + 1), uniform_counts),
            np.repeat(np.arange(1, num_frames + 1), foliage_counts),
        ]
    )
    target_ids = np.concatenate([gt.ids[found], np.full(len(uniform) + len(foliage), -1)])
    scores = np.concatenate(
        [
            rng.beta(*TARGET_SCORE, int(found.sum())),
            rng.beta(*CLUTTER_SCORE, len(uniform) + len(foliage)),
        ]
    )
    order = np.lexsort((rng.permutation(len(frames)), frames))
    corners = cxcywh_to_xywh(boxes[order])
    top_left = np.clip(corners[:, :2], 0, [width - 1, height - 1])
    bottom_right = np.clip(corners[:, :2] + corners[:, 2:], top_left + 1, [width, height])
    top_left = np.round(top_left, BOX_DECIMALS)
    sides = np.round(np.round(bottom_right, BOX_DECIMALS) - top_left, BOX_DECIMALS)
    table = MotTable.from_arrays(
        frames[order],
        np.full(len(order), -1),
        np.concatenate([top_left, sides], 1) + 0.0,
        np.clip(np.round(scores[order], 4), 1e-4, 1.0),
    )
    return table, target_ids[order]
