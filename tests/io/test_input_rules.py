"""Every rule on numbers read from MOT files and seqinfo.ini (jaxtrack.limits): file, line, why."""

from __future__ import annotations

import string
import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxtrack.errors import FileFormatError, InputWarning
from jaxtrack.io import load_sequence, read_mot_file, read_seqinfo
from jaxtrack.limits import (
    FLOAT32_MAX,
    FLOAT32_TINY,
    IMAGE_FACTOR,
    MAX_COORDINATE,
    MAX_FRAMES,
    MAX_ID,
    MAX_IMAGE_SIZE,
    MAX_SCORE,
    MIN_BOX_SIZE,
)
from jaxtrack.types import SequenceInfo

GOOD = "1,-1,10,20,30,40,0.9,-1,-1,-1"
#: A 640x480 image, 50 frames.
INFO = SequenceInfo("s", 50, 640, 480, 25.0)


def row(frame="1", ident="-1", x="10", y="20", w="30", h="40", conf="0.9", extra="-1,-1,-1"):
    return f"{frame},{ident},{x},{y},{w},{h},{conf},{extra}"


def read(tmp_path, rows, kind="det", **options):
    path = tmp_path / f"{kind}.txt"
    path.write_text("\n".join(rows) + "\n")
    return read_mot_file(path, kind, **options)


# (rows, kind, message): the error is on the last row (line len(rows)).
ABSOLUTE_RULES = {
    "frame_fraction": ([row(frame="2.5")], "det", "frame must be an integer"),
    "frame_zero": ([GOOD, row(frame="0")], "det", "frame 0 outside 1..1000000"),
    "frame_1e15": ([row(ident="1"), row(frame="1e15", ident="1")], "res", r"frame 1e\+15 outside"),
    "frame_1e9": ([row(frame="1e9", ident="1")], "gt", r"frame 1e\+09 outside 1\.\.1000000"),
    "frame_limit": ([row(frame=str(MAX_FRAMES + 1))], "det", "outside 1..1000000"),
    "id_fraction": ([row(ident="1.5")], "gt", "id must be an integer"),
    "det_id_below": ([row(ident="-2")], "det", r"det id must lie in \[-1, 2147483647\]"),
    "gt_id_negative": ([row(ident="-1")], "gt", r"gt id must lie in \[0, 2147483647\]"),
    "res_id_int32": ([row(ident=str(MAX_ID + 1))], "res", "res id must lie in"),
    "w_1e39": ([GOOD, row(w="1e39", h="1e39")], "det", r"column 5 \(w\) = 1e\+39 is not repr"),
    "x_1e39": ([row(ident="1", x="-1e39")], "gt", r"column 3 \(x\) = -1e\+39 is not representable"),
    "h_1e-46": ([GOOD, row(h="1e-46")], "det", r"column 6 \(h\) = 1e-46 is not representable"),
    "conf_1e-40": ([row(conf="1e-40")], "det", r"column 7 \(conf\) = 1e-40 is not repr"),
    "extra_1e300": ([row(ident="1", extra="-1,1e300,-1")], "gt", r"column 9 \(extra\) = 1e\+300"),
    "w_1e30": ([GOOD, GOOD, row(w="1e30", h="1e30")], "det", "w 1e\\+30 is beyond 2\\^20"),
    "h_1e8": ([row(h="1e8")], "det", "h 1e\\+08 is beyond 2\\^20 = 1048576 pixels"),
    "x_far": ([row(ident="1", x="2e6")], "res", "x 2e\\+06 is beyond 2\\^20"),
    "y_far": ([row(y="-2e6")], "det", "y -2e\\+06 is beyond 2\\^20"),
    "w_1e-30": ([row(w="1e-30")], "det", "w 1e-30 is below 1 pixel"),
    "h_subpixel_gt": ([row(ident="3", h="0.5")], "gt", "h 0.5 is below 1 pixel"),
    "w_normalised": ([row(w="0.05", h="0.2")], "det", "not normalised"),
    "res_w_zero": ([row(ident="3", w="0")], "res", "w must be positive, got 0"),
    "conf_huge": ([row(conf="2e6")], "det", "conf 2e\\+06 outside \\[-1e\\+06, 1e\\+06\\]"),
}


@pytest.mark.parametrize("case", sorted(ABSOLUTE_RULES))
def test_absolute_rules_name_file_and_line(tmp_path, case):
    rows, kind, message = ABSOLUTE_RULES[case]
    with pytest.raises(FileFormatError, match=message) as info:
        read(tmp_path, rows, kind)
    assert info.value.line == len(rows)
    assert str(info.value).startswith(f"{tmp_path / kind}.txt, line {len(rows)}: ")


def test_limits_themselves_are_legal(tmp_path):
    """The bounds are inclusive: exactly at each limit, a row loads."""
    rows = [
        row(frame=str(MAX_FRAMES), ident=str(MAX_ID), x=str(-MAX_COORDINATE), y="0",
            w=str(MAX_COORDINATE), h=str(MIN_BOX_SIZE), conf=str(-MAX_SCORE),
            extra=f"{FLOAT32_TINY!r},{-FLOAT32_MAX!r},0"),
    ]  # fmt: skip
    table = read(tmp_path, rows, "gt")
    assert table.frames[0] == MAX_FRAMES and table.ids[0] == MAX_ID
    res = read(tmp_path, [row(ident="0", w="1e-3", h="1e-3")], "res")
    assert res.boxes[0, 2] == 1e-3  # results may hold sub-pixel boxes, positive


def test_seq_length_bounds_frames(tmp_path):
    with pytest.raises(FileFormatError, match=r"frame 51 outside 1\.\.50 \(seqLength\)"):
        read(tmp_path, [GOOD, row(frame="51")], seq_length=50)
    with pytest.raises(FileFormatError, match=r"frame 51 outside 1\.\.50 \(seqLength\)"):
        read(tmp_path, [GOOD, row(frame="51")], info=INFO)


# With the 640x480 image of INFO: w <= 6400, h <= 4800, x in [-6400, 7040], y in [-4800, 5280].
IMAGE_RULES = {
    "w": (row(w="6401"), "w 6401 exceeds 10 times the 640x480 image"),
    "h": (row(h="4801"), "h 4801 exceeds 10 times the 640x480 image"),
    "x_left": (row(x="-6401"), "x -6401 lies more than 10 image widths outside"),
    "x_right": (row(x="7041"), "x 7041 lies more than 10 image widths outside"),
    "y_up": (row(y="-4801"), "y -4801 lies more than 10 image heights outside"),
    "y_down": (row(y="5281"), "y 5281 lies more than 10 image heights outside"),
}


@pytest.mark.parametrize("case", sorted(IMAGE_RULES))
@pytest.mark.parametrize("kind", ["det", "gt", "res"])
def test_image_relative_rules(tmp_path, case, kind):
    bad, message = IMAGE_RULES[case]
    bad = bad.replace(",-1,", ",7,", 1) if kind != "det" else bad
    with pytest.raises(FileFormatError, match=message) as info:
        read(tmp_path, [GOOD.replace(",-1,", ",3,", 1), bad], kind, info=INFO)
    assert info.value.line == 2
    # without an image size only the absolute rules apply
    assert len(read(tmp_path, [bad], kind)) == 1


def test_boxes_at_the_image_limits_load(tmp_path):
    w, h = IMAGE_FACTOR * 640, IMAGE_FACTOR * 480
    rows = [row(x=str(-w), y=str(-h), w=str(w), h=str(h)), row(x=str(11 * 640), y=str(11 * 480))]
    with pytest.warns(InputWarning, match="all 2 boxes lie outside"):
        assert len(read(tmp_path, rows, info=INFO)) == 2


def test_every_box_outside_the_image_warns(tmp_path):
    rows = [row(x="700", y="10"), row(x="10", y="500"), row(x="-50", w="50")]
    with pytest.warns(InputWarning, match=r"det\.txt: all 3 boxes lie outside the 640x480 image"):
        read(tmp_path, rows, info=INFO)
    inside = [*rows, row(x="-49", w="50")]  # one pixel column inside
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert len(read(tmp_path, inside, info=INFO)) == 4
        assert len(read(tmp_path, rows)) == 3  # no image size, no warning


def test_detection_scores_outside_0_1_warn(tmp_path):
    with pytest.warns(InputWarning, match=r"det\.txt, line 2: detection score 38\.5 outside"):
        read(tmp_path, [GOOD, row(conf="38.5")])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        read(tmp_path, [row(ident="4", conf="-1")], "res")  # results: any score


SEQINFO = (
    "[Sequence]\nname=s\nframeRate={rate}\nseqLength={length}\nimWidth={width}\nimHeight={height}\n"
)
SEQINFO_RULES = {
    "rate_1e300": ({"rate": "1e300"}, 3, r"frameRate must lie in \[1, 1000\], got 1e\+300"),
    "rate_1e-300": ({"rate": "1e-300"}, 3, r"frameRate must lie in \[1, 1000\]"),
    "rate_zero": ({"rate": "0"}, 3, "frameRate must lie in"),
    "rate_nan": ({"rate": "nan"}, 3, "frameRate must be finite"),
    "rate_inf": ({"rate": "inf"}, 3, "frameRate must be finite"),
    "rate_text": ({"rate": "fast"}, 3, r"frameRate must be a number in \[1, 1000\]"),
    "length_1e8": ({"length": "100000000"}, 4, r"seqLength must lie in \[1, 1000000\]"),
    "length_zero": ({"length": "0"}, 4, "seqLength must lie in"),
    "length_float": ({"length": "71.0"}, 4, r"seqLength must be an integer in \[1, 1000000\]"),
    "length_huge": ({"length": "9" * 5000}, 4, "seqLength must be an integer"),
    "width_1e8": ({"width": "100000000"}, 5, r"imWidth must lie in \[16, 65536\]"),
    "width_15": ({"width": "15"}, 5, "imWidth must lie in"),
    "height_big": ({"height": str(MAX_IMAGE_SIZE + 1)}, 6, "imHeight must lie in"),
    "height_exp": ({"height": "1e3"}, 6, "imHeight must be an integer"),
}


@pytest.mark.parametrize("case", sorted(SEQINFO_RULES))
def test_seqinfo_rules_name_file_line_and_key(tmp_path, case):
    values, line, message = SEQINFO_RULES[case]
    path = tmp_path / "seqinfo.ini"
    path.write_text(SEQINFO.format(**{"rate": 25, "length": 71, "width": 640, "height": 480,
                                      **values}))  # fmt: skip
    with pytest.raises(FileFormatError, match=message) as info:
        read_seqinfo(path)
    assert info.value.line == line and info.value.path == str(path)


def test_seqinfo_at_the_limits(tmp_path):
    path = tmp_path / "seqinfo.ini"
    path.write_text(SEQINFO.format(rate=1, length=MAX_FRAMES, width=16, height=160))
    info = read_seqinfo(path)
    assert (info.frame_rate, info.seq_length, info.im_width, info.im_height) == (
        1.0,
        MAX_FRAMES,
        16,
        160,
    )


def test_seqinfo_largest_image_and_aspect_ratio_warning(tmp_path):
    path = tmp_path / "seqinfo.ini"
    path.write_text(SEQINFO.format(rate=25, length=10, width=MAX_IMAGE_SIZE, height=MAX_IMAGE_SIZE))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_seqinfo(path).im_width == MAX_IMAGE_SIZE
    path.write_text(SEQINFO.format(rate=25, length=10, width=16, height=3960))
    with pytest.warns(InputWarning, match="a 16x3960 image is more than 10 times wider than high"):
        assert read_seqinfo(path).im_height == 3960


def test_seqinfo_reports_the_first_bad_line(tmp_path):
    path = tmp_path / "seqinfo.ini"
    path.write_text("[Sequence]\nimHeight=0\nframeRate=0\nseqLength=0\nimWidth=0\n")
    with pytest.raises(FileFormatError, match="imHeight must lie in") as info:
        read_seqinfo(path)
    assert info.value.line == 2


def write_sequence(folder, det_rows, length=50, width=640, height=480, gt_rows=None):
    (folder / "det").mkdir(parents=True)
    (folder / "seqinfo.ini").write_text(SEQINFO.format(rate=25, length=length, width=width,
                                                       height=height))  # fmt: skip
    (folder / "det" / "det.txt").write_text("".join(r + "\n" for r in det_rows))
    if gt_rows is not None:
        (folder / "gt").mkdir()
        (folder / "gt" / "gt.txt").write_text("".join(r + "\n" for r in gt_rows))
    return folder


def test_load_sequence_applies_the_image_rules(tmp_path):
    folder = write_sequence(tmp_path / "s", [GOOD, row(h="5000")])
    with pytest.raises(FileFormatError, match="line 2: h 5000 exceeds 10 times the 640x480"):
        load_sequence(folder)
    folder = write_sequence(tmp_path / "t", [GOOD], gt_rows=[row(ident="1", x="9000")])
    with pytest.raises(FileFormatError, match=r"gt\.txt, line 1: x 9000 lies more than"):
        load_sequence(folder)


def test_load_sequence_warnings(tmp_path):
    folder = write_sequence(tmp_path / "long", [GOOD, row(frame="20")], length=1000)
    with pytest.warns(InputWarning, match="seqLength is 1000 but the last row .* frame 20"):
        load_sequence(folder)
    folder = write_sequence(tmp_path / "empty", [])
    with pytest.warns(InputWarning, match="holds no detections: tracking it gives no tracks"):
        load_sequence(folder)
    folder = write_sequence(tmp_path / "span", [GOOD, row(frame="40")])
    with pytest.warns(InputWarning, match=r"no detections in frames 10\.\.20"):
        load_sequence(folder, frames=(10, 20))
    folder = write_sequence(tmp_path / "fine", [GOOD, row(frame="40")])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_sequence(folder)


# Property tests: any value in any column either loads (and then keeps every rule) or raises
# FileFormatError naming the file; never another exception or warning (numpy included).
number = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-(2**70), 2**70),
    st.sampled_from([0, 1, -1, 1e-46, 1e-39, 1e38, 1e39, 2**20, 2**31, MAX_FRAMES + 1]),
)
column_text = st.one_of(number.map(repr), st.text(string.digits + "e.-+", max_size=6))


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    values=st.lists(st.lists(column_text, min_size=10, max_size=10), min_size=1, max_size=4),
    kind=st.sampled_from(["det", "gt", "res"]),
    with_image=st.booleans(),
)
def test_any_numbers_load_within_the_rules_or_raise(tmp_path, values, kind, with_image):
    path = tmp_path / "rows.txt"
    path.write_text("".join(",".join(fields) + "\n" for fields in values))
    info = INFO if with_image else None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", InputWarning)
        try:
            table = read_mot_file(path, kind, info=info)
        except FileFormatError as err:
            assert err.path == str(path) and 1 <= err.line <= len(values)
            return
    assert np.all((table.frames >= 1) & (table.frames <= (50 if with_image else MAX_FRAMES)))
    assert np.all((table.ids >= -1) & (table.ids <= MAX_ID))
    for array in (table.boxes, table.confs, table.extra):
        assert np.array_equal(array.astype(np.float32) != 0, array != 0)  # no flush to zero
        assert np.all(np.isfinite(array.astype(np.float32)))
    assert np.all(np.abs(table.boxes) <= MAX_COORDINATE)
    assert np.all(table.boxes[:, 2:] >= (MIN_BOX_SIZE if kind != "res" else FLOAT32_TINY))
    if with_image:
        assert np.all(table.boxes[:, 2] <= IMAGE_FACTOR * 640)


seqinfo_value = st.one_of(
    number.map(repr),
    number.map(str),
    st.text(string.digits + "e.-+_ ", max_size=8),
)


@settings(
    max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(rate=seqinfo_value, length=seqinfo_value, width=seqinfo_value, height=seqinfo_value)
def test_any_seqinfo_values_load_within_the_rules_or_raise(tmp_path, rate, length, width, height):
    path = tmp_path / "seqinfo.ini"
    path.write_text(SEQINFO.format(rate=rate, length=length, width=width, height=height))
    try:
        info = read_seqinfo(path)
    except FileFormatError as err:
        assert err.path == str(path) and err.line in (3, 4, 5, 6)
        return
    assert 1 <= info.frame_rate <= 1000
    assert 1 <= info.seq_length <= MAX_FRAMES
    assert 16 <= info.im_width <= MAX_IMAGE_SIZE and 16 <= info.im_height <= MAX_IMAGE_SIZE
