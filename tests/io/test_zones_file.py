"""zones.json and its activity mask: round trip and a clear error for each bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from jaxtrack.context.zones import SceneZones
from jaxtrack.errors import FileFormatError
from jaxtrack.io.zones import activity_file, load_zones, save_zones

SIZE = (100, 60)  # width, height: an 8-pixel grid of 8 rows and 13 columns


@pytest.fixture
def zones() -> SceneZones:
    activity = np.zeros((8, 13), bool)
    activity[2:5, 3:11] = True
    boxes = np.array([[0.0, 10.5, 20.25, 30.0], [80.0, 0.0, 20.0, 60.0]])
    return SceneZones(boxes=boxes, activity=activity, cell_size=8.0)


def written(tmp_path, zones) -> tuple:
    path = tmp_path / "z.json"
    details = [{"entries": 3, "exits": 1}, {"entries": 0, "exits": 4}]
    files = save_zones(path, zones, SIZE, details, {"from": "gt"})
    return path, files, json.loads(path.read_text())


def test_round_trip(tmp_path, zones):
    path, files, data = written(tmp_path, zones)
    assert files == [path, tmp_path / "z.activity.png"] == [path, activity_file(path)]
    assert data["activity_mask"] == "z.activity.png" and data["zones"][0]["entries"] == 3
    loaded = load_zones(path)
    np.testing.assert_allclose(loaded.boxes, zones.boxes)
    np.testing.assert_array_equal(loaded.activity, zones.activity)
    assert loaded.cell_size == 8.0
    png = cv2.imread(str(files[1]), cv2.IMREAD_UNCHANGED)
    assert png.dtype == np.uint8 and set(np.unique(png)) == {0, 255}


def test_zones_without_a_mask(tmp_path, zones):
    path = tmp_path / "z.json"
    files = save_zones(path, zones._replace(activity=None, cell_size=None), SIZE)
    assert files == [path] and json.loads(path.read_text())["activity_mask"] is None
    loaded = load_zones(path)
    assert loaded.activity is None and loaded.cell_size is None and loaded.boxes.shape == (2, 4)


def rewrite(path, change) -> None:
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda d: d.pop("zones"), "missing key 'zones'"),
        (lambda d: d.update(zone=[]), "unknown key 'zone'"),
        (lambda d: d.update(format_version=2), "format_version must be 1"),
        (lambda d: d.update(image_width=0), "image_width must lie in"),
        (lambda d: d.update(zones={}), "zones must be a list"),
        (lambda d: d["zones"][1].update(w="wide"), r"zones\[1\].w must be a finite number"),
        (lambda d: d["zones"][1].pop("h"), r"zones\[1\]: missing key 'h'"),
        (lambda d: d["zones"][0].update(kind="entry"), r"zones\[0\]: unknown key 'kind'"),
        (lambda d: d["zones"][0].update(w=0), r"zones\[0\]: w and h must be positive"),
        (lambda d: d["zones"][1].update(x=81), r"zones\[1\]: box .* reaches outside"),
        (lambda d: d.pop("activity_cell"), "missing key 'activity_cell'"),
        (lambda d: d.update(activity_cell=0), "activity_cell must be"),
        (lambda d: d.update(activity_mask=None), "activity_cell is given but"),
        (lambda d: d.update(activity_mask=3), "activity_mask must be a file name or null"),
    ],
)
def test_bad_content_names_the_file_and_the_key(tmp_path, zones, change, message):
    path, _, _ = written(tmp_path, zones)
    rewrite(path, change)
    with pytest.raises(FileFormatError, match=message) as caught:
        load_zones(path)
    assert caught.value.path == str(path)


def test_bad_json_names_the_line(tmp_path):
    path = tmp_path / "z.json"
    path.write_text('{\n  "zones": [\n    {"x": 1,,}\n  ]\n}\n')
    with pytest.raises(FileFormatError, match="not valid JSON") as caught:
        load_zones(path)
    assert caught.value.line == 3
    path.write_text('{"zones": NaN}')
    with pytest.raises(FileFormatError, match="NaN is not allowed"):
        load_zones(path)
    with pytest.raises(FileFormatError, match="zones file not found"):
        load_zones(tmp_path / "missing.json")


def test_bad_mask_names_the_png(tmp_path, zones):
    path, files, _ = written(tmp_path, zones)
    mask = files[1]
    cv2.imwrite(str(mask), np.zeros((8, 12), np.uint8))
    with pytest.raises(FileFormatError, match=r"8x12 cells .* expected 8x13") as caught:
        load_zones(path)
    assert caught.value.path == str(mask)
    cv2.imwrite(str(mask), np.zeros((8, 13, 3), np.uint8))
    with pytest.raises(FileFormatError, match="must be a grey image"):
        load_zones(path)
    mask.write_bytes(b"not a png")
    with pytest.raises(FileFormatError, match="not a readable image"):
        load_zones(path)
    mask.unlink()
    with pytest.raises(FileFormatError, match=r"activity mask of .* not found"):
        load_zones(path)
