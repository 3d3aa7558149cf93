"""Frames of a scripted video scene (host NumPy/OpenCV): background, people, occluder, noise.

A frame is drawn in layers (:func:`render_frame`):

1. the static background (:func:`build_canvas`, drawn once from the scene's seed): paved
   ground with perspective joints, a brick wall with a door above each zone that touches the
   wall, the billboard (occluder), all lit by a horizontal illumination gradient
   (``ILLUMINATION`` from the left to the right edge) times a sunlit ellipse in
   ``config.bright_patch`` (``1 + BRIGHT_GAIN`` inside, soft edge);
2. the foliage: a two-tone leaf texture shown through the vegetation box at the frame's sway
   offset (:attr:`~jaxtrack.datasets.video_scene.VideoScene.vegetation_offsets`; it moves a
   few pixels in gusts, giving background subtraction its clutter);
3. the people, far to near (painter's order by foot row), each a flat-coloured figure
   (:func:`figure_polygons`): legs in the bottom colour, torso and arms in the top colour, a
   head in the skin colour; the occluder's pixels are pasted back over the people whose feet
   are above its bottom row (behind it);
4. Gaussian pixel noise of standard deviation ``noise_std``, added with saturation: a crop,
   at the frame's offset (:attr:`~jaxtrack.datasets.video_scene.VideoScene.noise_offsets`), of
   a noise field drawn once (so two frames share their noise only when they draw the same of
   the ``64^2`` offsets).

Frames are RGB ``uint8`` ``[H, W, 3]``. :func:`render_labels` draws the same people into a
map of ground-truth ids (0: background or occluder), the pixel truth of who is seen where.

Pixel ``(r, c)`` covers ``[c, c + 1) x [r, r + 1)``; polygons are filled with 4 bits of
sub-pixel precision and no anti-aliasing, so a person's pixels carry exactly its colours
before the noise.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import cv2
import numpy as np

from jaxtrack.datasets.video_paths import nominal_height
from jaxtrack.datasets.video_scene import NOISE_OFFSETS, VideoScene

#: Sub-pixel bits of the polygon vertices.
SHIFT = 4
#: Illumination factor at the left and right image edges.
ILLUMINATION = (0.85, 1.12)
#: Extra brightness inside the sunlit patch.
BRIGHT_GAIN = 0.35
#: Vertical bob of the body while walking: ``BOB h |sin(phase)|``, pixels.
BOB = 0.02
#: Figure quads (torso, left arm, right arm, left leg, right leg), 4 vertices each, as
#: ``(a_x, b_x, a_y, bobbed)``: a vertex of a person with foot point ``(f_x, f_y)``, box width
#: ``w`` and height ``h``, box top ``t = f_y - h``, stride ``s = sin(phase)`` (0 while
#: standing) and bob ``b`` lies at ``x = f_x + w (a_x + b_x s)``, ``y = t + a_y h + bobbed b``.
#: Every vertex stays within ``0.475 w`` of the centre column, inside the box.
FIGURE = np.array(
    [
        [(-0.325, 0, 0.17, 1), (0.325, 0, 0.17, 1), (0.2625, 0, 0.53, 1), (-0.2625, 0, 0.53, 1)],
        [
            (-0.35, 0, 0.18, 1),
            (-0.225, 0, 0.18, 1),
            (-0.2375, -0.125, 0.5, 1),
            (-0.3375, -0.125, 0.5, 1),
        ],
        [(0.225, 0, 0.18, 1), (0.35, 0, 0.18, 1), (0.3375, 0.125, 0.5, 1), (0.2375, 0.125, 0.5, 1)],
        [(-0.2375, 0, 0.5, 1), (-0.0125, 0, 0.5, 1), (0.025, 0.3, 1.0, 0), (-0.175, 0.3, 1.0, 0)],
        [(0.0125, 0, 0.5, 1), (0.2375, 0, 0.5, 1), (0.175, -0.3, 1.0, 0), (-0.025, -0.3, 1.0, 0)],
    ]
)
#: Which appearance colour (0 top, 1 bottom) fills each quad; quads are drawn legs first.
QUAD_COLOURS = (0, 0, 0, 1, 1)
DRAW_ORDER = (3, 4, 0, 1, 2)
#: Head: centre ``HEAD[0] h`` below the box top (plus the bob), radius ``HEAD[1] h`` (within
#: the box for aspect ratios from 0.3).
HEAD = (0.09, 0.075)
#: Colours (RGB) of the ground, wall, door, billboard frame and panel, and the foliage.
GROUND = (150, 146, 138)
WALL = (150, 100, 85)
DOOR = (70, 50, 40)
BOARD_FRAME = (60, 60, 65)
BOARD_PANEL = ((205, 70, 50), (235, 225, 200))
LEAVES = ((25, 58, 25), (80, 140, 55))
SKY = (175, 190, 210)
#: Foliage gaps (sky) where the leaf field (standard normal, smoothed) exceeds this.
FOLIAGE_GAP = 0.6
#: Seed stream of the canvas (the script uses the scene's seed alone).
CANVAS_STREAM = 1


class Canvas(NamedTuple):
    """The static layers of a scene's frames (:func:`build_canvas`).

    Attributes:
        background: RGB ``[H, W, 3]`` uint8: ground, wall, doors, occluder, foliage at rest.
        foliage: the leaf texture, RGB ``[vh + 2 m, vw + 2 m, 3]`` (``m`` the largest sway).
        noise_up: positive part of the noise field, ``[H + 64, W + 64, 3]`` uint8.
        noise_down: negative part of the noise field (same shape).
    """

    background: np.ndarray
    foliage: np.ndarray
    noise_up: np.ndarray
    noise_down: np.ndarray


def figure_polygons(
    boxes: np.ndarray, phase: np.ndarray, walking: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The shapes of people's figures (vectorised over people).

    Args:
        boxes: ``(x, y, w, h)`` boxes, ``[n, 4]`` pixels.
        phase: gait phase of each person, radians.
        walking: False for a person standing (legs together, arms down, no bob).

    Returns:
        ``heads [n, 3]`` (centre column, centre row, radius) and ``quads [n, 5, 4, 2]``
        (torso, left arm, right arm, left leg, right leg; :data:`FIGURE`), pixels.
    """
    stride = np.sin(phase) * walking
    width, height = boxes[:, 2], boxes[:, 3]
    centre = boxes[:, 0] + width / 2
    top = boxes[:, 1]
    bob = BOB * height * np.abs(stride)
    ax, bx, ay, bobbed = (FIGURE[..., k][None] for k in range(4))
    w, h = width[:, None, None], height[:, None, None]
    xs = centre[:, None, None] + w * (ax + bx * stride[:, None, None])
    ys = top[:, None, None] + h * ay + bobbed * bob[:, None, None]
    heads = np.stack([centre, top + HEAD[0] * height + bob, HEAD[1] * height], axis=1)
    return heads, np.stack([xs, ys], axis=-1)


def build_canvas(scene: VideoScene) -> Canvas:
    """Draws the static layers of a scene's frames (from its seed; see the module docstring).

    Args:
        scene: the scene.

    Returns:
        The canvas.
    """
    config = scene.config
    rng = np.random.default_rng((scene.seed, CANVAS_STREAM))
    width, height = config.image_width, config.image_height
    ground_row = round(config.ground_row * height)
    image = _smooth_field(rng, (height, width), (8, 10), 10.0) + GROUND
    image += rng.normal(0, 5, (height, width, 1))
    _paving(image, scene, ground_row)
    wall = _smooth_field(rng, (ground_row, width), (3, 10), 8.0) + WALL
    wall += rng.normal(0, 6, (ground_row, width, 1))
    image[:ground_row] = wall
    _bricks(image, ground_row)
    _doors(image, scene, ground_row)
    image *= _lighting(config)[..., None]
    _billboard(image, scene.occluder)
    sway = int(np.abs(scene.vegetation_offsets).max(initial=0))
    x0, y0, x1, y1 = pixel_bounds(scene.vegetation)
    foliage = _leaves(rng, (y1 - y0 + 2 * sway, x1 - x0 + 2 * sway))
    image[y0:y1, x0:x1] = foliage[sway : sway + y1 - y0, sway : sway + x1 - x0]
    noise = np.round(
        rng.normal(0, config.noise_std, (height + NOISE_OFFSETS, width + NOISE_OFFSETS, 3))
    )
    return Canvas(
        background=np.clip(np.round(image), 0, 255).astype(np.uint8),
        foliage=foliage,
        noise_up=np.clip(noise, 0, 255).astype(np.uint8),
        noise_down=np.clip(-noise, 0, 255).astype(np.uint8),
    )


def render_frame(scene: VideoScene, canvas: Canvas, frame: int) -> np.ndarray:
    """Draws one frame (see the module docstring).

    Args:
        scene: the scene.
        canvas: its static layers (:func:`build_canvas`).
        frame: 1-based frame number.

    Returns:
        RGB ``uint8`` ``[H, W, 3]``.
    """
    image = canvas.background.copy()
    x0, y0, x1, y1 = pixel_bounds(scene.vegetation)
    sway = (canvas.foliage.shape[0] - (y1 - y0)) // 2
    dx, dy = scene.vegetation_offsets[frame - 1] + sway
    image[y0:y1, x0:x1] = canvas.foliage[dy : dy + y1 - y0, dx : dx + x1 - x0]
    rows = scene.frame_rows(frame)
    ids = scene.gt_table.ids[rows] - 1
    look = scene.appearance
    colours = np.stack([look.top[ids], look.bottom[ids], look.skin[ids]], axis=1)
    ox0, oy0, ox1, oy1 = pixel_bounds(scene.occluder)

    def occluder(target):
        target[oy0:oy1, ox0:ox1] = canvas.background[oy0:oy1, ox0:ox1]

    _paint(image, scene, rows, colours, occluder)
    ox, oy = scene.noise_offsets[frame - 1]
    height, width = image.shape[:2]
    image = cv2.add(image, canvas.noise_up[oy : oy + height, ox : ox + width])
    return cv2.subtract(image, canvas.noise_down[oy : oy + height, ox : ox + width])


def render_labels(scene: VideoScene, frame: int) -> np.ndarray:
    """The ground-truth id seen at each pixel of a frame (0: background or occluder).

    Args:
        scene: the scene.
        frame: 1-based frame number.

    Returns:
        ``uint16`` ``[H, W]``.
    """
    config = scene.config
    labels = np.zeros((config.image_height, config.image_width), np.uint16)
    rows = scene.frame_rows(frame)
    ids = scene.gt_table.ids[rows]
    ox0, oy0, ox1, oy1 = pixel_bounds(scene.occluder)

    def occluder(target):
        target[oy0:oy1, ox0:ox1] = 0

    _paint(labels, scene, rows, np.repeat(ids[:, None, None], 3, axis=1), occluder)
    return labels


def render_frames(
    scene: VideoScene, first: int = 1, last: int | None = None
) -> Iterator[np.ndarray]:
    """The frames ``first..last`` (1-based, inclusive; default: all), drawn one at a time."""
    canvas = build_canvas(scene)
    for frame in range(first, (last or scene.config.num_frames) + 1):
        yield render_frame(scene, canvas, frame)


def _paint(target, scene: VideoScene, rows, colours, occluder) -> None:
    """People of ``rows`` far to near, the occluder pasted after those behind it.

    ``colours[i]`` holds the (top, bottom, skin) values of row ``i`` (RGB, or an id).
    """
    boxes = scene.gt_table.boxes[rows]
    heads, quads = figure_polygons(boxes, scene.gt_phase[rows], scene.gt_walking[rows])
    heads = np.round(np.concatenate([heads[:, :2] - 0.5, heads[:, 2:]], 1) * 2**SHIFT)
    heads = heads.astype(np.int32)
    quads = np.round((quads - 0.5) * 2**SHIFT).astype(np.int32)
    feet = boxes[:, 1] + boxes[:, 3]
    base = scene.occluder[1] + scene.occluder[3]
    order = np.argsort(feet, kind="stable")
    behind = int(np.searchsorted(feet[order], base))
    for position, index in enumerate(order):
        if position == behind:
            occluder(target)
        values = [tuple(int(v) for v in np.atleast_1d(value)) for value in colours[index]]
        for part in DRAW_ORDER:
            colour = values[QUAD_COLOURS[part]]
            cv2.fillConvexPoly(target, quads[index, part], colour, cv2.LINE_8, SHIFT)
        x, y, radius = heads[index]
        cv2.circle(target, (int(x), int(y)), int(radius), values[2], -1, cv2.LINE_8, SHIFT)
    if behind == len(order):
        occluder(target)


def pixel_bounds(box: np.ndarray) -> tuple[int, int, int, int]:
    """``(x0, y0, x1, y1)``: the pixel columns ``x0..x1 - 1`` and rows ``y0..y1 - 1`` of a box."""
    x, y, w, h = box
    return round(x), round(y), round(x + w), round(y + h)


def _smooth_field(rng, shape, cells, amplitude) -> np.ndarray:
    """Low-frequency brightness variation ``[*shape, 1]``: a ``cells`` grid of normal draws,
    bicubically enlarged."""
    coarse = rng.normal(0, amplitude, cells).astype(np.float32)
    field = cv2.resize(coarse, shape[::-1], interpolation=cv2.INTER_CUBIC)
    return field.astype(np.float64)[..., None]


def _paving(image, scene: VideoScene, ground_row: int) -> None:
    """Paving joints: rows spaced by a third of a person's height, columns converging on the
    horizon's centre."""
    config = scene.config
    height, width = image.shape[:2]
    joint = np.array(GROUND) - 30
    row = float(ground_row)
    while row < height:
        cv2.line(image, (0, round(row)), (width, round(row)), joint.tolist(), 1)
        row += max(2.0, float(nominal_height(row, config)) / 3)
    vanish = (width / 2, config.horizon_row * height)
    for bottom in np.linspace(-width, 2 * width, 25):
        t = (ground_row - vanish[1]) / (height - vanish[1])
        top = vanish[0] + t * (bottom - vanish[0])
        cv2.line(image, (round(top), ground_row), (round(bottom), height), joint.tolist(), 1)


def _bricks(image, ground_row: int) -> None:
    """Mortar lines on the wall: courses of 1/50 of the image height, staggered joints."""
    height, width = image.shape[:2]
    course = max(3, height // 50)
    brick = 3 * course
    mortar = (np.array(WALL) + 40).tolist()
    for k, row in enumerate(range(0, ground_row, course)):
        cv2.line(image, (0, row), (width, row), mortar, 1)
        for column in range((k % 2) * brick // 2, width, brick):
            cv2.line(image, (column, row), (column, min(row + course, ground_row)), mortar, 1)


def _doors(image, scene: VideoScene, ground_row: int) -> None:
    """A door in the wall above each zone whose box reaches up to the wall's foot."""
    config = scene.config
    door_height = 1.9 * float(nominal_height(ground_row, config))
    for box in scene.zones:
        if box[1] <= ground_row + 0.02 * config.image_height:
            x0, x1 = round(box[0] - 0.1 * box[2]), round(box[0] + 1.1 * box[2])
            top = max(round(ground_row - door_height), 0)
            image[top:ground_row, x0:x1] = DOOR


def _lighting(config) -> np.ndarray:
    """Illumination factor per pixel: the horizontal gradient times the sunlit ellipse."""
    height, width = config.image_height, config.image_width
    gradient = np.linspace(*ILLUMINATION, width)[None, :].repeat(height, 0)
    x, y, w, h = config.pixels(config.bright_patch)
    patch = np.zeros((height, width), np.float32)
    cv2.ellipse(
        patch,
        (round(x + w / 2), round(y + h / 2)),
        (round(w / 2), round(h / 2)),
        0,
        0,
        360,
        1.0,
        -1,
    )
    blur = max(3, round(0.05 * width)) | 1
    patch = cv2.GaussianBlur(patch, (blur, blur), 0)
    return gradient * (1 + BRIGHT_GAIN * patch)


def _billboard(image, occluder: np.ndarray) -> None:
    """The occluder: a dark frame around a striped poster panel."""
    x0, y0, x1, y1 = pixel_bounds(occluder)
    image[y0:y1, x0:x1] = BOARD_FRAME
    border = max(1, (x1 - x0) // 12)
    stripes = max(1, (y1 - y0 - 2 * border) // 6)
    for k, row in enumerate(range(y0 + border, y1 - border, stripes)):
        image[row : min(row + stripes, y1 - border), x0 + border : x1 - border] = BOARD_PANEL[k % 2]


def _leaves(rng, shape) -> np.ndarray:
    """Foliage: dark and light leaf clumps (about a tenth of the region wide) with gaps of sky
    (the smoothed field above ``FOLIAGE_GAP``), and grain; RGB uint8."""
    cells = (max(2, shape[0] // 10), max(2, shape[1] // 10))
    field = cv2.resize(rng.normal(size=cells).astype(np.float32), shape[::-1])[..., None]
    texture = np.where(field > 0, LEAVES[1], LEAVES[0]).astype(np.float64)
    texture = np.where(field > FOLIAGE_GAP, SKY, texture)
    texture += rng.normal(0, 8, (*shape, 1))
    return np.clip(np.round(texture), 0, 255).astype(np.uint8)
