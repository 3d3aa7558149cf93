"""Video writing and frame annotation (jaxtrack.io.video writer additions)."""

from __future__ import annotations

import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.io.video import FrameWriter, VideoReader, annotate_frame, id_colour


def _frames(count=6, size=(64, 48)):
    rng = np.random.default_rng(0)
    return [rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8) for _ in range(count)]


def test_mp4_round_trip_has_all_frames_at_the_size(tmp_path):
    path = tmp_path / "out.mp4"
    with FrameWriter(path, (64, 48), fps=7) as writer:
        for k, frame in enumerate(_frames(), start=1):
            writer.write(frame, k)
    with VideoReader(path) as reader:
        assert (reader.num_frames, reader.width, reader.height) == (6, 64, 48)
        assert reader.fps == pytest.approx(7)


def test_png_folder_is_exact_and_numbered_by_frame(tmp_path):
    frames = _frames(3)
    with FrameWriter(tmp_path / "pngs", (64, 48)) as writer:
        for k, frame in zip((5, 6, 7), frames, strict=True):
            writer.write(frame, k)
    assert sorted(p.name for p in (tmp_path / "pngs").iterdir()) == [
        "000005.png",
        "000006.png",
        "000007.png",
    ]
    with VideoReader(tmp_path / "pngs") as reader:
        np.testing.assert_array_equal(reader.read(2), frames[1])


def test_writer_refuses_a_frame_of_another_size(tmp_path):
    with FrameWriter(tmp_path / "pngs", (64, 48)) as writer, pytest.raises(InputError):
        writer.write(np.zeros((10, 10, 3), np.uint8), 1)


def test_annotate_draws_box_in_id_colour_and_keeps_the_input():
    image = np.zeros((60, 80, 3), np.uint8)
    out = annotate_frame(image, np.array([[10, 20, 30, 25]]), ids=np.array([7]))
    assert not image.any()
    colour = np.array(id_colour(7))
    assert id_colour(7) != id_colour(8)
    np.testing.assert_array_equal(out[45, 25], colour)  # bottom edge (y + h = 45)
    np.testing.assert_array_equal(out[30, 10], colour)  # left edge
    assert not out[32, 25].any()  # inside stays untouched


def test_annotate_detections_trails_and_overlay():
    image = np.zeros((60, 80, 3), np.uint8)
    boxes = np.array([[5, 5, 10, 10]])
    out = annotate_frame(image, boxes)
    np.testing.assert_array_equal(out[5, 8], [255, 255, 255])
    trail = annotate_frame(
        image, np.zeros((0, 4)), np.zeros(0, int), {3: np.array([[0, 50], [70, 50]])}
    )
    assert trail[50, 30].any()
    overlay = np.zeros((60, 80))
    overlay[:, 40:] = 1.0
    heat = annotate_frame(image, np.zeros((0, 4)), overlay=overlay)
    assert heat[:, 45:].mean() > heat[:, :35].mean() + 20
