"""Clutter labels file: exact round trip, validation naming file and entry, frame draw."""

from __future__ import annotations

import json

import numpy as np
import pytest

from jaxtrack.context.clutter_labels import (
    FORMAT_VERSION,
    ClutterLabels,
    choose_frames,
    clutter_mask,
    load_clutter_labels,
    save_clutter_labels,
)
from jaxtrack.errors import FileFormatError, InputError


def example_labels() -> ClutterLabels:
    return ClutterLabels(
        sequence="PETS09-S2L1",
        image_size=(768, 576),
        labelled_frames=[12, 57, 301],
        frames=[57, 57, 301],
        boxes=[[612.0, 101.5, 27.0, 61.0], [0.1, 0.2, 1e-3 / 3, 7.25], [-3.5, 500.0, 20.0, 44.0]],
        pending_frames=[650, 402],
    )


def valid_document() -> dict:
    return {
        "format_version": FORMAT_VERSION,
        "sequence": "S",
        "image_width": 640,
        "image_height": 480,
        "labelled_frames": [1, 4],
        "pending_frames": [9],
        "clutter": [{"frame": 4, "box": [1, 2, 3, 4]}],
    }


def test_round_trip_is_exact(tmp_path):
    labels = example_labels()
    path = tmp_path / "sub" / "labels.json"
    save_clutter_labels(path, labels)
    loaded = load_clutter_labels(path)
    assert loaded.sequence == "PETS09-S2L1"
    assert loaded.image_size == (768, 576)
    assert loaded.labelled_frames.dtype == np.int64 and loaded.frames.dtype == np.int64
    np.testing.assert_array_equal(loaded.labelled_frames, [12, 57, 301])
    np.testing.assert_array_equal(loaded.pending_frames, [650, 402])
    np.testing.assert_array_equal(loaded.frames, [57, 57, 301])
    assert loaded.boxes.dtype == np.float64 and loaded.boxes.shape == (3, 4)
    assert np.array_equal(loaded.boxes, labels.boxes)  # bit-exact, including 1e-3 / 3
    assert len(loaded) == 3 and loaded.clutter_per_frame == pytest.approx(1.0)
    document = json.loads(path.read_text())
    assert document["format_version"] == FORMAT_VERSION
    assert document["clutter"][0] == {"frame": 57, "box": [612.0, 101.5, 27.0, 61.0]}
    assert sorted(p.name for p in path.parent.iterdir()) == ["labels.json"]  # no temp left


def test_empty_labels_round_trip(tmp_path):
    empty = ClutterLabels("S", (10, 10), [], [], [])
    save_clutter_labels(tmp_path / "e.json", empty)
    loaded = load_clutter_labels(tmp_path / "e.json")
    assert loaded.boxes.shape == (0, 4) and loaded.labelled_frames.size == 0
    assert loaded.clutter_per_frame == 0.0


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda d: d.pop("sequence"), "missing key 'sequence'"),
        (lambda d: d.update(extra=1), "unknown key 'extra'"),
        (lambda d: d.update(format_version=2), "format_version must be 1, got 2"),
        (lambda d: d.update(sequence=""), "sequence must be a non-empty string"),
        (lambda d: d.update(image_width=0), "image_width must be a positive integer, got 0"),
        (lambda d: d.update(image_height=4.5), "image_height must be a positive integer"),
        (lambda d: d.update(labelled_frames=[1, True]), r"labelled_frames\[1\] must be"),
        (lambda d: d.update(labelled_frames=[4, 1]), "labelled_frames must be in ascending"),
        (lambda d: d.update(labelled_frames=[1, 4, 4]), r"labelled_frames\[2\]: frame 4 appears"),
        (lambda d: d.update(labelled_frames="1,4"), "labelled_frames must be a list"),
        (lambda d: d.update(pending_frames=[0]), r"pending_frames\[0\] must be a positive"),
        (lambda d: d.update(pending_frames=[4]), "frame 4 is in both"),
        (lambda d: d.update(clutter={}), "clutter must be a list"),
        (lambda d: d["clutter"].append([4, 1, 2, 3, 4]), r"clutter\[1\] must be an object"),
        (lambda d: d["clutter"][0].update(score=1), r"clutter\[0\] must be an object with"),
        (lambda d: d["clutter"][0].update(frame=2), r"clutter\[0\]\.frame 2 is not in labelled"),
        (lambda d: d["clutter"][0].update(frame="4"), r"clutter\[0\]\.frame must be a positive"),
        (lambda d: d["clutter"][0].update(box=[1, 2, 3]), r"clutter\[0\]\.box must be 4 finite"),
        (lambda d: d["clutter"][0].update(box=[1, "2", 3, 4]), r"clutter\[0\]\.box must be 4"),
        (lambda d: d["clutter"][0].update(box=[1, 2, 0, 4]), r"clutter\[0\]\.box width and"),
        (lambda d: d["clutter"][0].update(box=[1, 2, 3, -4]), r"clutter\[0\]\.box width and"),
        (
            lambda d: d["clutter"].append({"frame": 4, "box": [1.0, 2.0, 3.0, 4.0]}),
            r"clutter\[1\] repeats clutter\[0\]",
        ),
    ],
)
def test_each_validation_error_names_file_and_entry(tmp_path, edit, message):
    document = valid_document()
    path = tmp_path / "labels.json"
    path.write_text(json.dumps(document))
    load_clutter_labels(path)  # the unedited document is valid
    edit(document)
    path.write_text(json.dumps(document))
    with pytest.raises(FileFormatError, match=message) as info:
        load_clutter_labels(path)
    assert info.value.path == str(path)
    assert str(info.value).startswith(str(path))


def test_file_level_errors(tmp_path):
    with pytest.raises(FileFormatError, match="labels file not found"):
        load_clutter_labels(tmp_path / "missing.json")
    path = tmp_path / "labels.json"
    path.write_text('{\n  "format_version": 1,\n  "sequence": "S"\n  "image_width": 3\n}\n')
    with pytest.raises(FileFormatError, match="not valid JSON") as info:
        load_clutter_labels(path)
    assert info.value.line == 4  # where the missing comma is noticed
    path.write_bytes(b'{\n"sequence": "\xff"}')
    with pytest.raises(FileFormatError, match="not UTF-8") as info:
        load_clutter_labels(path)
    assert info.value.line == 2
    path.write_text("[1, 2]")
    with pytest.raises(FileFormatError, match="top level must be a JSON object"):
        load_clutter_labels(path)
    document = valid_document()
    document["clutter"][0]["box"] = [1, 2, 3, float("nan")]
    path.write_text(json.dumps(document))
    with pytest.raises(FileFormatError, match="NaN is not allowed"):
        load_clutter_labels(path)


def test_constructor_rejects_inconsistent_labels():
    with pytest.raises(ValueError, match=r"clutter\[0\]\.frame 5 is not in labelled_frames"):
        ClutterLabels("S", (10, 10), [1], [5], [[0, 0, 1, 1]])
    with pytest.raises(ValueError, match="box width and height must be positive"):
        ClutterLabels("S", (10, 10), [1], [1], [[0, 0, 0, 1]])


def test_choose_frames_is_seeded_distinct_and_in_span():
    frames = choose_frames(101, 400, 20, seed=3)
    assert frames.shape == (20,) and np.unique(frames).size == 20
    assert frames.min() >= 101 and frames.max() <= 400
    assert np.all(np.diff(frames) > 0)
    np.testing.assert_array_equal(frames, choose_frames(101, 400, 20, seed=3))
    assert not np.array_equal(frames, choose_frames(101, 400, 20, seed=4))
    np.testing.assert_array_equal(choose_frames(5, 9, 20, seed=0), [5, 6, 7, 8, 9])
    with pytest.raises(InputError, match=">= 1"):
        choose_frames(1, 9, 0, seed=0)
    with pytest.raises(InputError, match="seed"):
        choose_frames(1, 9, 3, seed=-1)


def test_clutter_mask_matches_exact_boxes():
    labels = ClutterLabels("S", (100, 100), [2, 3], [2, 3], [[1.5, 2, 3, 4], [10, 10, 5, 5]])
    frames = np.array([2, 2, 3, 3, 4])
    boxes = np.array(
        [[1.5, 2, 3, 4], [10, 10, 5, 5], [1.5, 2, 3, 4], [10, 10, 5, 5], [10, 10, 5, 5]]
    )
    np.testing.assert_array_equal(
        clutter_mask(labels, frames, boxes), [True, False, False, True, False]
    )
    boxes[0, 0] = 1.5000000001
    with pytest.raises(InputError, match=r"clutter\[0\] \(frame 2, box 1.5,2,3,4\) matches no"):
        clutter_mask(labels, frames, boxes)
