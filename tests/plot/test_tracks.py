"""PHD frame figure: the artists drawn, PNGs on synthetic and PETS09 frames, bad input."""

from __future__ import annotations

import dataclasses

import jax
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.image import imread

from jaxtrack.association.estimates import Estimates
from jaxtrack.datasets import SceneConfig, generate_scene
from jaxtrack.filters import default_phd_params, phd_filter, run
from jaxtrack.io import load_sequence
from jaxtrack.io.video import VideoReader
from jaxtrack.pipelines.tracking import phd_frame_snapshot
from jaxtrack.plot.tracks import (
    ESTIMATE_COLOUR,
    PARTICLE_MAX_ALPHA,
    draw_phd_frame,
    phd_frame_figure,
    track_colour,
)
from jaxtrack.types import Tracks

WIDTH, HEIGHT = 320, 240


def _axes():
    figure = Figure()
    FigureCanvasAgg(figure)
    return figure.add_subplot()


def _frame_data():
    """50 particles (one without mass), 3 of 4 estimate slots used, 5 frames of tracks."""
    rng = np.random.default_rng(0)
    particles = np.zeros((50, 6))
    particles[:, [0, 2]] = rng.uniform([0, 0], [WIDTH, HEIGHT], (50, 2))
    particles[:, 4:] = 20.0
    log_weights = np.log(rng.uniform(0.1, 1.0, 50))
    log_weights[7] = -1e30
    log_weights[3] = np.log(2.0)
    states = np.zeros((4, 6))
    states[:, [0, 2, 4, 5]] = [
        [50, 60, 20, 40],
        [150, 100, 25, 50],
        [0, 0, 1, 1],
        [250, 180, 30, 60],
    ]
    estimates = Estimates(
        states=states,
        masses=np.array([0.93, 1.2, 0.0, 0.61]),
        scores=np.ones(4),
        mask=np.array([True, True, False, True]),
    )
    boxes = np.zeros((5, 3, 4))
    ids = np.full((5, 3), -1)
    mask = np.zeros((5, 3), bool)
    for t in range(5):  # id 7 in every frame, moving right; id 3 in the last two frames
        boxes[t, 0], ids[t, 0], mask[t, 0] = [40 + 10 * t, 40, 20, 40], 7, True
    for t in (3, 4):
        boxes[t, 2], ids[t, 2], mask[t, 2] = [200, 150 + 5 * t, 30, 60], 3, True
    mask[2, 1], ids[2, 1], boxes[2, 1] = True, 12, [100, 100, 20, 40]  # ended before the frame
    tracks = Tracks(boxes=boxes, ids=ids, scores=mask * 0.9, mask=mask)
    return particles, log_weights, estimates, tracks


def test_draw_phd_frame_draws_particles_estimates_and_tracks():
    particles, log_weights, estimates, tracks = _frame_data()
    ax = _axes()
    draw_phd_frame(ax, particles, log_weights, estimates, tracks, image_size=(WIDTH, HEIGHT))

    (scatter,) = ax.collections
    np.testing.assert_allclose(scatter.get_offsets(), particles[:, [0, 2]])
    alphas = scatter.get_facecolors()[:, 3]
    relative = np.exp(log_weights - log_weights.max())
    np.testing.assert_allclose(alphas, PARTICLE_MAX_ALPHA * relative, atol=1e-6)
    assert alphas[3] == pytest.approx(PARTICLE_MAX_ALPHA) and alphas[7] == 0.0

    dashed = [p for p in ax.patches if p.get_linestyle() == "--"]
    solid = [p for p in ax.patches if p.get_linestyle() == "-"]
    assert len(ax.patches) == 3 + 2
    assert len(dashed) == 3 and len(solid) == 2
    assert all(p.get_edgecolor() == to_rgba(ESTIMATE_COLOUR) for p in dashed)
    assert dashed[0].get_xy() == (40, 40) and dashed[0].get_width() == 20
    assert [p.get_edgecolor() for p in solid] == [track_colour(7), track_colour(3)]
    assert solid[0].get_xy() == (80, 40)

    trails = {len(line.get_xdata()): line for line in ax.lines}
    assert sorted(trails) == [2, 5]
    np.testing.assert_allclose(trails[5].get_xdata(), 50 + 10 * np.arange(5))
    assert to_rgba(trails[2].get_color()) == track_colour(3)
    texts = {text.get_text() for text in ax.texts}
    assert {"0.93", "1.20", "0.61", "7", "3"} <= texts and "12" not in texts
    assert ax.get_xlim() == (0, WIDTH) and ax.get_ylim() == (HEIGHT, 0)
    assert not ax.images


def test_draw_phd_frame_over_an_image_and_bad_images():
    particles, log_weights, estimates, tracks = _frame_data()
    image = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    ax = _axes()
    draw_phd_frame(ax, particles, log_weights, estimates, tracks, image)
    assert len(ax.images) == 1 and ax.get_xlim() == (0, WIDTH)
    for bad in (image.astype(np.float32), image[..., 0]):
        with pytest.raises(ValueError, match="uint8"):
            draw_phd_frame(_axes(), particles, log_weights, estimates, tracks, bad)
    with pytest.raises(ValueError, match="image size"):
        draw_phd_frame(_axes(), particles, log_weights, estimates, tracks)
    with pytest.raises(ValueError, match="log_weights"):
        draw_phd_frame(_axes(), particles, log_weights[:-1], estimates, tracks, image)


def test_draw_phd_frame_without_trails():
    particles, log_weights, estimates, tracks = _frame_data()
    ax = _axes()
    last = jax.tree.map(lambda x: x[-1:], tracks)
    draw_phd_frame(ax, particles, log_weights, estimates, last, image_size=(WIDTH, HEIGHT))
    assert len(ax.patches) == 5 and all(len(line.get_xdata()) == 1 for line in ax.lines)


@pytest.fixture(scope="module")
def synthetic():
    scene = generate_scene(3, dataclasses.replace(SceneConfig(), num_frames=24))
    info = scene.info
    params = default_phd_params(info.im_width, info.im_height, info.frame_rate)
    return scene, params, phd_filter(256, births_per_detection=8)


def test_phd_frame_figure_writes_a_png_of_the_image_size(synthetic, tmp_path):
    scene, params, filt = synthetic
    snapshot = phd_frame_snapshot(filt, jax.random.key(0), params, scene.detections, 20, trail=10)
    assert snapshot.tracks.mask.shape[0] == 11 and snapshot.frame_index == 20
    path = phd_frame_figure(
        snapshot,
        out_path=tmp_path / "figures" / "frame.png",
        first_frame=1,
        image_size=(scene.info.im_width, scene.info.im_height),
    )
    assert path == tmp_path / "figures" / "frame.png"
    pixels = imread(path)
    height, width = pixels.shape[:2]
    assert width >= scene.info.im_width and height >= scene.info.im_height
    assert np.unique(pixels.reshape(-1, pixels.shape[-1]), axis=0).shape[0] > 10


@pytest.mark.parametrize("frame_index", [-1, 24, 100])
def test_phd_frame_figure_rejects_frames_out_of_range(synthetic, tmp_path, frame_index):
    scene, params, filt = synthetic
    with pytest.raises(ValueError, match=r"frame_index .* outside 0\.\.23.*24 frames"):
        phd_frame_snapshot(filt, jax.random.key(0), params, scene.detections, frame_index)


def test_run_over_a_prefix_of_the_frames_matches_the_whole_run(synthetic):
    """What phd_frame_snapshot relies on: the first frames do not depend on the later ones."""
    scene, params, filt = synthetic
    key = jax.random.key(5)
    _, whole = jax.jit(lambda d: run(filt, key, params, d))(scene.detections)
    prefix = jax.tree.map(lambda x: x[:10], scene.detections)
    _, first = jax.jit(lambda d: run(filt, key, params, d))(prefix)
    np.testing.assert_array_equal(first.tracks.ids, whole.tracks.ids[:10])
    np.testing.assert_allclose(first.estimates.states, whole.estimates.states[:10], atol=1e-4)
    np.testing.assert_allclose(first.mass, whole.mass[:10], rtol=1e-6)


def test_phd_frame_figure_over_a_pets09_video_frame(data_root, tmp_path):
    sequence = load_sequence(data_root / "mot15" / "PETS09-S2L1", frames=(1, 8))
    info = sequence.info
    with VideoReader(data_root / "video" / "vtest.avi") as video:
        image = video.read(8)
    snapshot = phd_frame_snapshot(
        phd_filter(256, births_per_detection=8),
        jax.random.key(0),
        default_phd_params(info.im_width, info.im_height, info.frame_rate),
        sequence.detections,
        frame_index=7,
    )
    path = phd_frame_figure(
        snapshot,
        out_path=tmp_path / "pets.png",
        image=image,
        first_frame=sequence.first_frame,
    )
    pixels = imread(path)
    assert pixels.shape[0] >= info.im_height and pixels.shape[1] >= info.im_width
    assert pixels[..., :3].std() > 0.05
