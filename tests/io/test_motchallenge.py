"""MOTChallenge reader/writer: round trips on real data, padding invariants, bad input."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.io import (
    MotTable,
    load_sequence,
    pad_detections,
    parse_frame_span,
    read_mot_file,
    read_seqinfo,
    write_mot_file,
    write_results,
)
from jaxtrack.types import PAD_BOX
from tests.data import MOT15_SEQUENCES


def assert_tables_equal(a: MotTable, b: MotTable) -> None:
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.ids, b.ids)
    np.testing.assert_array_equal(a.boxes, b.boxes)
    np.testing.assert_array_equal(a.confs, b.confs)
    np.testing.assert_array_equal(a.extra, b.extra)


def test_all_eleven_sequences_present(mot15_root):
    assert len(MOT15_SEQUENCES) == 11


@pytest.mark.parametrize("name", MOT15_SEQUENCES)
def test_round_trip_exact(mot15_root, tmp_path, name):
    seq = load_sequence(mot15_root / name)
    for kind, table in (("det", seq.det_table), ("gt", seq.gt_table)):
        out = tmp_path / f"{kind}.txt"
        write_mot_file(out, table)
        again = read_mot_file(out, kind, seq.info.seq_length)
        assert_tables_equal(table, again)
        assert len(again) == sum(1 for line in open(table.path) if line.strip())


@pytest.mark.parametrize("name", MOT15_SEQUENCES)
def test_padding_invariants(mot15_root, name):
    seq = load_sequence(mot15_root / name)
    det = seq.detections
    num_frames = seq.info.seq_length
    assert det.boxes.shape[:2] == det.mask.shape == det.scores.shape
    assert det.boxes.shape[0] == num_frames
    assert int(det.mask.sum()) == len(seq.det_table)
    counts = np.bincount(seq.det_table.frames - 1, minlength=num_frames)
    np.testing.assert_array_equal(det.mask.sum(axis=1), counts)
    # real slots come first in each frame, in file order
    assert np.all(det.mask[:, :-1] >= det.mask[:, 1:])
    np.testing.assert_allclose(det.boxes[~det.mask], np.tile(PAD_BOX, (int((~det.mask).sum()), 1)))
    assert np.all(det.scores[~det.mask] == 0)
    frame = int(np.argmax(counts)) + 1
    rows = seq.det_table.frames == frame
    np.testing.assert_allclose(
        det.boxes[frame - 1, : counts[frame - 1]], seq.det_table.boxes[rows], rtol=1e-6
    )
    gt = seq.ground_truth
    assert int(gt.mask.sum()) == len(seq.gt_table)
    assert np.all(gt.ids[~gt.mask] == -1)
    assert int(gt.ignored.sum()) == int((seq.gt_table.confs == 0).sum())
    assert not np.any(gt.ignored & ~gt.mask)


def test_pets_counts(mot15_root):
    seq = load_sequence(mot15_root / "PETS09-S2L1")
    assert seq.info.seq_length == 795
    assert (seq.info.im_width, seq.info.im_height) == (768, 576)
    assert len(seq.det_table) == 4359
    assert len(np.unique(seq.gt_table.ids)) == 19


def test_frame_span(mot15_root):
    seq = load_sequence(mot15_root / "PETS09-S2L1", frames=(401, 795))
    assert seq.num_frames == 395
    assert seq.detections.boxes.shape[0] == 395
    assert seq.det_table.frames.min() >= 401 and seq.gt_table.frames.min() >= 401
    full = load_sequence(mot15_root / "PETS09-S2L1")
    np.testing.assert_array_equal(
        seq.detections.boxes, full.detections.boxes[400:, : seq.detections.boxes.shape[1]]
    )
    assert parse_frame_span("401:", 795) == (401, 795)
    assert parse_frame_span(":10", 795) == (1, 10)
    for bad in ["0:10", "10:5", "1:796", "a:b", "3"]:
        with pytest.raises(InputError):
            parse_frame_span(bad, 795)


def test_capacity_too_small_is_an_error(mot15_root):
    with pytest.raises(InputError, match=r"frame 133 .* has 9 rows but max_detections=5"):
        load_sequence(mot15_root / "PETS09-S2L1", max_detections=5)
    seq = load_sequence(mot15_root / "PETS09-S2L1", max_detections=20)
    assert seq.detections.boxes.shape[1] == 20


def test_write_results_sorted_and_readable(tmp_path):
    boxes = np.array([[1.5, 2.25, 10, 20], [3, 4, 5, 6], [7, 8, 9, 10]])
    write_results(tmp_path / "r.txt", [2, 1, 1], [5, 9, 3], boxes, [0.5, 0.25, 1.0])
    lines = (tmp_path / "r.txt").read_text().splitlines()
    assert lines == [
        "1,3,7,8,9,10,1,-1,-1,-1",
        "1,9,3,4,5,6,0.25,-1,-1,-1",
        "2,5,1.5,2.25,10,20,0.5,-1,-1,-1",
    ]
    table = read_mot_file(tmp_path / "r.txt", "res")
    np.testing.assert_array_equal(table.ids, [3, 9, 5])


def make_sequence_copy(mot15_root: Path, tmp_path: Path, name: str = "TUD-Campus") -> Path:
    dst = tmp_path / name
    shutil.copytree(mot15_root / name, dst)
    for f in dst.rglob("*"):
        f.chmod(0o644 if f.is_file() else 0o755)
    return dst


GOOD = "1,-1,10,10,5,20,0.9,-1,-1,-1\n"
BAD_ROWS = {
    "too_few_columns": ("1,-1,10,10,5,20\n", 1, "columns"),
    "too_many_columns": ("1,-1,10,10,5,20,1,1,1,1,1\n", 1, "columns"),
    "inconsistent_columns": (GOOD + "2,-1,10,10,5,20,0.9\n", 2, "columns but line 1 has 10"),
    "non_numeric": (GOOD + GOOD + "3,-1,ten,10,5,20,0.9,-1,-1,-1\n", 3, "column 3 is not a number"),
    "nan": ("1,-1,nan,10,5,20,0.9,-1,-1,-1\n", 1, "NaN or inf"),
    "inf": (GOOD + "1,-1,10,inf,5,20,0.9,-1,-1,-1\n", 2, "NaN or inf"),
    "negative_width": ("1,-1,10,10,-5,20,0.9,-1,-1,-1\n", 1, "w -5 is below 1 pixel"),
    "zero_height": (GOOD + "1,-1,10,10,5,0,0.9,-1,-1,-1\n", 2, "h 0 is below 1 pixel"),
    "frame_zero": ("0,-1,10,10,5,20,0.9,-1,-1,-1\n", 1, "frame 0 outside 1..71"),
    "frame_too_large": (GOOD + "72,-1,10,10,5,20,0.9,-1,-1,-1\n", 2, "frame 72 outside 1..71"),
    "fractional_frame": ("1.5,-1,10,10,5,20,0.9,-1,-1,-1\n", 1, "frame must be an integer"),
}


@pytest.mark.parametrize("case", sorted(BAD_ROWS))
def test_bad_detection_file(mot15_root, tmp_path, case):
    text, line, message = BAD_ROWS[case]
    seq_dir = make_sequence_copy(mot15_root, tmp_path)
    (seq_dir / "det" / "det.txt").write_text(text)
    with pytest.raises(FileFormatError, match=message) as info:
        load_sequence(seq_dir)
    assert info.value.line == line
    assert info.value.path.endswith("det/det.txt")
    assert f"det.txt, line {line}:" in str(info.value)


def test_duplicate_gt_id_in_frame(mot15_root, tmp_path):
    seq_dir = make_sequence_copy(mot15_root, tmp_path)
    gt = seq_dir / "gt" / "gt.txt"
    lines = gt.read_text().splitlines()
    lines.insert(5, lines[2])
    gt.write_text("\n".join(lines) + "\n")
    with pytest.raises(
        FileFormatError, match="appears twice in frame 1 \\(also on line 3\\)"
    ) as info:
        load_sequence(seq_dir)
    assert info.value.line == 6 and info.value.path.endswith("gt/gt.txt")


def test_duplicate_result_id(tmp_path):
    (tmp_path / "r.txt").write_text(
        "1,1,0,0,5,5,1,-1,-1,-1\n2,1,0,0,5,5,1,-1,-1,-1\n2,1,3,0,5,5,1,-1,-1,-1\n"
    )
    with pytest.raises(FileFormatError, match="line 3: id 1 appears twice in frame 2"):
        read_mot_file(tmp_path / "r.txt", "res")


def test_missing_files(mot15_root, tmp_path):
    with pytest.raises(FileFormatError, match="sequence folder not found"):
        load_sequence(tmp_path / "nope")
    seq_dir = make_sequence_copy(mot15_root, tmp_path)
    (seq_dir / "det" / "det.txt").unlink()
    with pytest.raises(FileFormatError, match=r"det\.txt: file not found"):
        load_sequence(seq_dir)
    (seq_dir / "seqinfo.ini").unlink()
    with pytest.raises(FileFormatError, match=r"seqinfo\.ini: file not found"):
        load_sequence(seq_dir)


def test_gt_is_optional(mot15_root, tmp_path):
    seq_dir = make_sequence_copy(mot15_root, tmp_path)
    shutil.rmtree(seq_dir / "gt")
    seq = load_sequence(seq_dir)
    assert seq.gt_table is None and seq.ground_truth is None


BAD_SEQINFO = {
    "no_section": ("seqLength=10\nimWidth=5\n", None, "no \\[Sequence\\] section"),
    "missing_key": ("[Sequence]\nname=x\nimWidth=5\nimHeight=5\n", None, "missing key 'seqLength'"),
    "not_integer": ("[Sequence]\nseqLength=ten\nimWidth=5\nimHeight=5\n", 2, "seqLength must be"),
    "negative": ("[Sequence]\nseqLength=10\nimWidth=-5\nimHeight=5\n", 3, "imWidth must lie in"),
    "no_equals": ("[Sequence]\nseqLength 10\n", 2, "expected 'key=value'"),
    "bad_header": ("[Sequence\nseqLength=10\n", 1, "malformed section header"),
    "bad_rate": (
        "[Sequence]\nframeRate=fast\nseqLength=1\nimWidth=5\nimHeight=5\n",
        2,
        "frameRate",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_SEQINFO))
def test_bad_seqinfo(tmp_path, case):
    text, line, message = BAD_SEQINFO[case]
    path = tmp_path / "seqinfo.ini"
    path.write_text(text)
    with pytest.raises(FileFormatError, match=message) as info:
        read_seqinfo(path)
    assert info.value.line == line


def test_seqinfo_values(mot15_root):
    info = read_seqinfo(mot15_root / "ADL-Rundle-6" / "seqinfo.ini")
    assert (info.name, info.seq_length, info.im_width, info.im_height, info.frame_rate) == (
        "ADL-Rundle-6",
        525,
        1920,
        1080,
        30.0,
    )


def test_mot16_nine_column_gt(tmp_path):
    path = tmp_path / "gt.txt"
    path.write_text("1,1,10,10,5,20,1,1,0.8\n1,2,30,10,5,20,0,7,1\n")
    table = read_mot_file(path, "gt")
    np.testing.assert_array_equal(table.ignored, [False, True])
    np.testing.assert_array_equal(table.extra, [[1, 0.8], [7, 1]])


def test_whitespace_separated_and_blank_lines(tmp_path):
    path = tmp_path / "det.txt"
    path.write_text("1 -1 10 10 5 20 0.9\n\n2, -1, 1, 1, 2, 2, 0.5\n")
    table = read_mot_file(path, "det")
    np.testing.assert_array_equal(table.lines, [1, 3])
    np.testing.assert_array_equal(table.frames, [1, 2])
    path.write_text("1 -1 10 10 5 20 0.9\n\n2, -1, 1, 1, 2, 2, 0.5, -1\n")
    with pytest.raises(FileFormatError, match="line 3: got 8 columns but line 1 has 7"):
        read_mot_file(path, "det")


def test_pad_detections_from_table():
    table = MotTable.from_arrays(
        [3, 3, 5], [-1, -1, -1], [[0, 0, 2, 2], [1, 1, 3, 3], [2, 2, 4, 4]]
    )
    det = pad_detections(table, first_frame=3, num_frames=4)
    assert det.boxes.shape == (4, 2, 4)
    np.testing.assert_array_equal(det.mask, [[1, 1], [0, 0], [1, 0], [0, 0]])
    with pytest.raises(InputError, match=r"outside frames 4\.\.7"):
        pad_detections(table, first_frame=4, num_frames=4)


def test_empty_table_round_trip(tmp_path):
    table = MotTable.from_arrays([], [], np.zeros((0, 4)))
    assert len(table) == 0 and table.extra.shape == (0, 3)
    write_mot_file(tmp_path / "empty.txt", table)
    assert len(read_mot_file(tmp_path / "empty.txt", "res")) == 0
    det = pad_detections(table, first_frame=1, num_frames=3)
    assert det.boxes.shape == (3, 1, 4) and not det.mask.any()
