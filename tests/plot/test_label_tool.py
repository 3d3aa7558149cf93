"""ClutterLabeller driven headlessly: synthetic clicks and keys on an Agg canvas."""

from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.backend_bases import CloseEvent, KeyEvent, MouseButton, MouseEvent
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from jaxtrack.context.clutter_labels import load_clutter_labels
from jaxtrack.io import MotTable, load_sequence
from jaxtrack.io.video import VideoReader
from jaxtrack.plot.label_tool import (
    CANVAS_GREY,
    CLUTTER_COLOUR,
    OBJECT_COLOUR,
    ClutterLabeller,
)

IMAGE_SIZE = (200, 150)
BIG = [10.0, 10.0, 40.0, 80.0]  # frame 3
SMALL = [20.0, 30.0, 10.0, 20.0]  # frame 3, inside BIG
APART = [100.5, 50.25, 30.0, 30.0]  # frame 3
OTHER = [60.0, 60.0, 20.0, 40.0]  # frame 5
UNSHOWN = [1.0, 1.0, 5.0, 5.0]  # frame 2, not among the frames to label


def centre(box) -> tuple[float, float]:
    return box[0] + box[2] / 2, box[1] + box[3] / 2


def make_table() -> MotTable:
    boxes = [BIG, SMALL, APART, OTHER, UNSHOWN]
    return MotTable.from_arrays([3, 3, 3, 5, 2], [-1] * 5, boxes, [0.9] * 5)


def make_labeller(out, frames=(3, 5, 8), **kwargs) -> ClutterLabeller:
    figure = Figure(figsize=(4, 3))
    FigureCanvasAgg(figure)
    return ClutterLabeller(
        figure,
        make_table(),
        frames,
        out,
        sequence="SYN",
        image_size=IMAGE_SIZE,
        **kwargs,
    )


def click(labeller: ClutterLabeller, x: float, y: float, button=MouseButton.LEFT) -> None:
    """A press at image coordinates (x, y), dispatched through the canvas's callbacks."""
    canvas = labeller.figure.canvas
    canvas.draw()
    display_x, display_y = labeller.ax.transData.transform((x, y))
    event = MouseEvent("button_press_event", canvas, display_x, display_y, button=button)
    canvas.callbacks.process("button_press_event", event)


def press(labeller: ClutterLabeller, key: str) -> None:
    canvas = labeller.figure.canvas
    canvas.callbacks.process("key_press_event", KeyEvent("key_press_event", canvas, key))


def colours(labeller: ClutterLabeller) -> list[str]:
    """'clutter' / 'object' per rectangle of the shown frame, in box order."""
    named = {to_rgba(CLUTTER_COLOUR): "clutter", to_rgba(OBJECT_COLOUR): "object"}
    return [named[tuple(r.get_edgecolor())] for r in labeller.rectangles]


def test_starts_on_first_frame_with_green_boxes(tmp_path):
    labeller = make_labeller(tmp_path / "l.json")
    assert labeller.frame == 3
    assert colours(labeller) == ["object"] * 3
    assert [list(r.get_bbox().bounds) for r in labeller.rectangles] == [BIG, SMALL, APART]
    assert "frame 3  (1/3)" in labeller.ax.get_title()
    assert "clutter 0 of 3" in labeller.ax.get_title()
    image = labeller.image.get_array()
    assert image.shape == (150, 200, 3) and np.all(image == CANVAS_GREY)


def test_click_toggles_on_and_off(tmp_path):
    labeller = make_labeller(tmp_path / "l.json")
    click(labeller, *centre(APART))
    assert colours(labeller) == ["object", "object", "clutter"]
    assert "clutter 1 of 3" in labeller.ax.get_title()
    click(labeller, APART[0] + 1, APART[1] + 1)  # another point of the same box
    assert colours(labeller) == ["object"] * 3
    assert not labeller.is_clutter.any()


def test_overlapping_boxes_take_the_smallest(tmp_path):
    labeller = make_labeller(tmp_path / "l.json")
    click(labeller, *centre(SMALL))
    assert colours(labeller) == ["object", "clutter", "object"]
    click(labeller, BIG[0] + 2, BIG[1] + 70)  # inside BIG, outside SMALL
    assert colours(labeller) == ["clutter", "clutter", "object"]


def test_clicks_that_do_nothing(tmp_path):
    labeller = make_labeller(tmp_path / "l.json")
    click(labeller, 150.0, 120.0)  # inside the image, outside every box
    click(labeller, *centre(SMALL), button=MouseButton.RIGHT)
    click(labeller, *centre(UNSHOWN))  # box of a frame that is not shown
    canvas = labeller.figure.canvas
    canvas.callbacks.process(
        "button_press_event",
        MouseEvent("button_press_event", canvas, 1, 1, button=MouseButton.LEFT),  # off the axes
    )
    assert colours(labeller) == ["object"] * 3
    assert not labeller.is_clutter.any()


def test_next_previous_keys_and_save(tmp_path):
    out = tmp_path / "labels.json"
    labeller = make_labeller(out)
    click(labeller, *centre(SMALL))
    press(labeller, "n")
    assert labeller.frame == 5 and colours(labeller) == ["object"]
    click(labeller, *centre(OTHER))
    press(labeller, "right")
    assert labeller.frame == 8 and labeller.rectangles == []
    press(labeller, "n")  # already on the last frame
    assert labeller.frame == 8 and "last frame" in labeller.ax.get_title()
    press(labeller, "p")
    assert labeller.frame == 5 and colours(labeller) == ["clutter"]
    press(labeller, "left")
    press(labeller, "left")  # already on the first frame
    assert labeller.frame == 3 and colours(labeller) == ["object", "clutter", "object"]
    assert len(labeller.ax.patches) == 3  # the other frames' rectangles were removed
    assert not out.exists()
    press(labeller, "s")
    document = json.loads(out.read_text())
    assert document["sequence"] == "SYN"
    assert (document["image_width"], document["image_height"]) == IMAGE_SIZE
    assert document["labelled_frames"] == [3, 5, 8] and document["pending_frames"] == []
    assert document["clutter"] == [{"frame": 3, "box": SMALL}, {"frame": 5, "box": OTHER}]
    assert "saved" in labeller.ax.get_title()


def test_partial_session_keeps_pending_frames_and_resumes(tmp_path):
    out = tmp_path / "labels.json"
    labeller = make_labeller(out, frames=(5, 3, 8))
    click(labeller, *centre(OTHER))
    press(labeller, "n")
    click(labeller, *centre(APART))
    press(labeller, "q")
    assert labeller.closed
    labels = load_clutter_labels(out)
    np.testing.assert_array_equal(labels.labelled_frames, [3, 5])
    np.testing.assert_array_equal(labels.pending_frames, [8])
    np.testing.assert_array_equal(labels.frames, [3, 5])
    np.testing.assert_array_equal(labels.boxes, [APART, OTHER])
    click(labeller, *centre(SMALL))  # closed: no effect
    press(labeller, "n")
    assert labeller.frame == 3 and load_clutter_labels(out).frames.size == 2

    frames = np.concatenate([labels.labelled_frames, labels.pending_frames])
    resumed = make_labeller(out, frames=frames, resume=labels)
    assert resumed.frame == 8  # the first frame not labelled yet
    press(resumed, "p")
    assert resumed.frame == 5 and colours(resumed) == ["clutter"]
    press(resumed, "p")
    assert colours(resumed) == ["object", "object", "clutter"]
    canvas = resumed.figure.canvas
    canvas.callbacks.process("close_event", CloseEvent("close_event", canvas))
    assert resumed.closed
    again = load_clutter_labels(out)
    np.testing.assert_array_equal(again.labelled_frames, [3, 5, 8])
    assert again.pending_frames.size == 0
    np.testing.assert_array_equal(again.boxes, labels.boxes)


def test_resume_rejects_other_sequence_and_frames(tmp_path):
    out = tmp_path / "labels.json"
    labeller = make_labeller(out)
    labeller.close()
    labels = load_clutter_labels(out)
    with pytest.raises(ValueError, match="labelled frame 3 is not among"):
        make_labeller(out, frames=(5, 8), resume=labels)
    figure = Figure()
    FigureCanvasAgg(figure)
    with pytest.raises(ValueError, match="labels are for SYN"):
        ClutterLabeller(
            figure, make_table(), (3,), out, sequence="X", image_size=IMAGE_SIZE, resume=labels
        )
    with pytest.raises(ValueError, match="distinct"):
        make_labeller(out, frames=(3, 3))


def test_frame_source_pixels_are_shown(tmp_path):
    def source(frame: int) -> np.ndarray:
        return np.full((150, 200, 3), frame * 10, dtype=np.uint8)

    labeller = make_labeller(tmp_path / "l.json", frame_source=source)
    assert np.all(labeller.image.get_array() == 30)
    press(labeller, "n")
    assert np.all(labeller.image.get_array() == 50)
    with pytest.raises(ValueError, match="expected 200x150"):
        make_labeller(tmp_path / "l.json", frame_source=lambda frame: np.zeros((5, 5, 3)))


def test_on_real_detections_and_video(tmp_path, mot15_root, data_root):
    sequence = load_sequence(mot15_root / "PETS09-S2L1", frames=(1, 2))
    table = sequence.det_table
    out = tmp_path / "pets.json"
    with VideoReader(data_root / "video" / "vtest.avi") as reader:
        figure = Figure(figsize=(6, 4.5))
        FigureCanvasAgg(figure)
        labeller = ClutterLabeller(
            figure,
            table,
            [2, 1],
            out,
            sequence=sequence.info.name,
            image_size=(768, 576),
            frame_source=reader.read,
        )
        np.testing.assert_array_equal(labeller.image.get_array(), reader.read(2))
        rows = np.flatnonzero(table.frames == 2)
        # the smallest box of frame 2, clicked at its centre, is always the one chosen
        row = rows[np.argmin(table.boxes[rows, 2] * table.boxes[rows, 3])]
        click(labeller, *centre(table.boxes[row]))
        press(labeller, "q")
    labels = load_clutter_labels(out)
    assert labels.sequence == "PETS09-S2L1"
    np.testing.assert_array_equal(labels.labelled_frames, [2])
    np.testing.assert_array_equal(labels.pending_frames, [1])
    np.testing.assert_array_equal(labels.frames, [2])
    assert np.array_equal(labels.boxes, table.boxes[[row]])  # exactly as in det.txt
