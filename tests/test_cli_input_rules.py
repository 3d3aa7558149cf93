"""Hostile input through the CLI: every reproduction of issue 14 exits 2 with one line.

Each case copies TUD-Campus (seqinfo.ini, det, gt) into a temporary folder, edits one value and
runs the command: exit status 2, one error line naming the file and line (or the option), no
traceback, the inputs untouched and nothing written. Legal but suspicious values warn on one
stderr line and the command goes on.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from jaxtrack.cli import main
from jaxtrack.io import read_mot_file
from jaxtrack.limits import (
    MAX_FRAME_RATE,
    MAX_IMAGE_SIZE,
    MIN_BOX_SIZE,
    MIN_FRAME_RATE,
    MIN_IMAGE_SIZE,
)
from tests.data import REPO_ROOT


@pytest.fixture
def campus(mot15_root, tmp_path):
    """A writable copy of TUD-Campus (seqinfo.ini, det/det.txt, gt/gt.txt)."""
    source, folder = mot15_root / "TUD-Campus", tmp_path / "X"
    for name in ("seqinfo.ini", "det/det.txt", "gt/gt.txt"):
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(source / name, folder / name)
    return folder


def edit_box(folder, index: int, w: str, h: str, name: str = "det/det.txt") -> int:
    """Sets w and h of row ``index`` (0-based) of a MOT file; returns its 1-based line."""
    path = folder / name
    lines = path.read_text().splitlines()
    fields = lines[index].split(",")
    fields[4], fields[5] = w, h
    lines[index] = ",".join(fields)
    path.write_text("\n".join(lines) + "\n")
    return index + 1


def edit_seqinfo(folder, key: str, value: str) -> int:
    """Sets one key of seqinfo.ini; returns its line."""
    path = folder / "seqinfo.ini"
    lines = path.read_text().splitlines()
    number = next(i for i, line in enumerate(lines) if line.startswith(f"{key}="))
    lines[number] = f"{key}={value}"
    path.write_text("\n".join(lines) + "\n")
    return number + 1


def snapshot(folder) -> dict:
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def one_error_line(capsys, command: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"jaxtrack {command}: error: ") and "Traceback" not in err
    return lines[0]


BOXES = {
    "1e30": (100, "1e30", "w 1e+30 is beyond 2^20"),
    "1e39": (100, "1e39", "column 5 (w) = 1e+39 is not representable in float32"),
    "1e-46": (100, "1e-46", "column 5 (w) = 1e-46 is not representable in float32"),
    "1e8_frame_1": (0, "1e8", "w 1e+08 is beyond 2^20"),
    "1e-30_frame_1": (0, "1e-30", "w 1e-30 is below 1 pixel"),
}


@pytest.mark.parametrize("case", sorted(BOXES))
@pytest.mark.parametrize("command", ["track", "inspect", "learn-context"])
def test_hostile_box_sizes_exit_2(campus, tmp_path, capsys, case, command):
    index, value, message = BOXES[case]
    line = edit_box(campus, index, value, value)
    before = snapshot(campus)
    out = tmp_path / "out" / ("x.npz" if command == "learn-context" else "x.txt")
    argv = [command, str(campus)] + ([] if command == "inspect" else ["--out", str(out)])
    assert main([*argv, "--quiet"] if command != "inspect" else argv) == 2
    error = one_error_line(capsys, command)
    assert f"{campus / 'det' / 'det.txt'}, line {line}: {message}" in error
    assert snapshot(campus) == before and not out.parent.exists()


SEQINFO = {
    "rate_1e300": ("frameRate", "1e300", "frameRate must lie in [1, 1000], got 1e+300"),
    "rate_1e-300": ("frameRate", "1e-300", "frameRate must lie in [1, 1000], got 1e-300"),
    "width_1e8": ("imWidth", "100000000", "imWidth must lie in [16, 65536], got 100000000"),
    "length_1e8": ("seqLength", "100000000", "seqLength must lie in [1, 1000000]"),
}


@pytest.mark.parametrize("case", sorted(SEQINFO))
@pytest.mark.parametrize("command", ["track", "inspect"])
def test_hostile_seqinfo_exits_2(campus, tmp_path, capsys, case, command):
    key, value, message = SEQINFO[case]
    line = edit_seqinfo(campus, key, value)
    if key == "imWidth":
        edit_seqinfo(campus, "imHeight", value)
    before = snapshot(campus)
    out = tmp_path / "x.txt"
    argv = [command, str(campus)] + (["--out", str(out), "--quiet"] if command == "track" else [])
    assert main(argv) == 2
    error = one_error_line(capsys, command)
    assert f"{campus / 'seqinfo.ini'}, line {line}: {message}" in error
    assert snapshot(campus) == before and not out.exists()


def test_tiny_images_are_refused(campus, capsys):
    """The issue's 10x10 image: below the smallest image; 16x16 refuses its large boxes."""
    line = edit_seqinfo(campus, "imWidth", "10")
    edit_seqinfo(campus, "imHeight", "10")
    assert main(["inspect", str(campus)]) == 2
    error = one_error_line(capsys, "inspect")
    assert f"seqinfo.ini, line {line}: imWidth must lie in [16, 65536], got 10" in error
    edit_seqinfo(campus, "imWidth", "16")
    edit_seqinfo(campus, "imHeight", "16")
    assert main(["inspect", str(campus)]) == 2
    assert "w 166.431 exceeds 10 times the 16x16 image" in one_error_line(capsys, "inspect")


def test_every_detection_outside_the_image_warns_and_goes_on(campus, capsys):
    edit_seqinfo(campus, "imWidth", "100")
    edit_seqinfo(campus, "imHeight", "100")
    assert main(["inspect", str(campus), "--json"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out)["detections"] == 321
    warnings = captured.err.strip().splitlines()
    assert len(warnings) == 2  # det.txt and gt.txt, one line each
    assert warnings[0].startswith("jaxtrack inspect: warning: ")
    assert "det.txt: all 321 boxes lie outside the 100x100 image" in warnings[0]
    assert "gt.txt: all 359 boxes" in warnings[1]


def test_seq_length_far_beyond_the_data_warns(campus, capsys):
    edit_seqinfo(campus, "seqLength", "1000000")
    assert main(["inspect", str(campus), "--json", "--frames", "1:71"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("jaxtrack inspect: warning: seqLength is 1000000 but the last row")
    assert len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("frame", ["1000000000000000", "1000000000", "1000001"])
def test_eval_without_seqinfo_bounds_frames_before_allocating(campus, tmp_path, capsys, frame):
    result = tmp_path / "res.txt"
    result.write_text(f"1,1,10,10,50,100,1,-1,-1,-1\n{frame},1,10,10,50,100,1,-1,-1,-1\n")
    gt = campus / "gt" / "gt.txt"
    assert main(["eval", "--gt", str(gt), "--res", str(result)]) == 2
    error = one_error_line(capsys, "eval")
    assert f"{result}, line 2: frame {float(frame):g} outside 1..1000000" in error


def test_eval_with_seqinfo_applies_the_image_rules_to_results(campus, tmp_path, capsys):
    result = tmp_path / "res.txt"
    result.write_text("1,1,10,10,50,100,1,-1,-1,-1\n2,1,10,10,50,9000,1,-1,-1,-1\n")
    gt, seqinfo = campus / "gt" / "gt.txt", campus / "seqinfo.ini"
    assert main(["eval", "--gt", str(gt), "--res", str(result), "--seqinfo", str(seqinfo)]) == 2
    assert "line 2: h 9000 exceeds 10 times the 640x480 image" in one_error_line(capsys, "eval")


OPTIONS = [
    (["track", "{seq}", "--out", "{tmp}/x.txt", "--seed", "-1"], "argument --seed: value must"),
    (["track", "{seq}", "--out", "{tmp}/x.txt", "--seed", "1e3"], "argument --seed: must be an"),
    (["track", "{seq}", "--out", "{tmp}/x.txt", "--figure-frame", "0"], "--figure-frame"),
    (["track", "{seq}", "--out", "{tmp}/x.txt", "--frames", "1:99999999999"], "frame span"),
    (["inspect", "{seq}", "--iou", "1.5"], r"argument --iou: value must lie in (0, 1]"),
    (["inspect", "{seq}", "--iou", "nan"], "argument --iou: value must be finite"),
    (["eval", "{seq}", "{tmp}/r.txt", "--iou-threshold", "0"], "--iou-threshold"),
    (["eval", "{seq}", "{tmp}/r.txt", "--centre-threshold", "inf"], "--centre-threshold"),
    (["eval", "{seq}", "{tmp}/r.txt", "--ospa-c", "-1"], "--ospa-c"),
    (["eval", "{seq}", "{tmp}/r.txt", "--ospa-p", "1e300"], "--ospa-p: value must lie in [1, 10]"),
    (["tune", "{seq}", "--out", "{tmp}/c.json", "--learning-rate", "1e-50"], "float32"),
    (["tune", "{seq}", "--out", "{tmp}/c.json", "--keys", "100000"], "--keys"),
    (["tune", "{seq}", "--out", "{tmp}/c.json", "--particles", "0"], "--particles"),
    (["learn-context", "{seq}", "--out", "{tmp}/c.npz", "--clutter-epochs", "0"], "epochs"),
    (["learn-context", "{seq}", "--out", "{tmp}/c.npz", "--fps", "1e300"], "--fps"),
    (["simulate", "--out", "{tmp}/s", "--num-frames", "100000000"], "--num-frames"),
    (["simulate", "--out", "{tmp}/s", "--preview-frame", "-3"], "--preview-frame"),
    (["detect", "{tmp}/v.avi", "--out", "{tmp}/d.txt", "--train-frames", "2"], "--train-frames"),
    (["track-video", "{tmp}/v.avi", "--out", "{tmp}/r.txt", "--trail", "-1"], "--trail"),
    (["label-clutter", "{seq}", "--out", "{tmp}/l.json", "--num-frames", "0"], "--num-frames"),
]


@pytest.mark.parametrize(("argv", "message"), OPTIONS)
def test_numeric_options_are_range_checked_by_name(campus, tmp_path, capsys, argv, message):
    argv = [arg.format(seq=campus, tmp=tmp_path) for arg in argv]
    assert main(argv) == 2
    assert message in one_error_line(capsys, argv[0])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["X"]


def test_hostile_scene_config_exits_2(tmp_path, capsys):
    config = tmp_path / "scene.json"
    for text, message in (
        ('{"birth_rate": 1000}', "birth_rate must lie in [0, 10], got 1000"),
        ('{"max_box_size": [64, 1e30]}', "max_box_size[1] must lie in"),
        ('{"birth_rate": NaN}', "NaN is not a number"),
    ):
        config.write_text(text)
        assert main(["simulate", "--out", str(tmp_path / "s"), "--scene-config", str(config)]) == 2
        assert f"{config}: {message}" in one_error_line(capsys, "simulate")
    assert not (tmp_path / "s").exists()


def test_subprocess_one_line_no_traceback_no_numpy_warning(campus, tmp_path):
    """The float32 overflow case used to leak a NumPy RuntimeWarning and track nothing."""
    edit_box(campus, 100, "1e39", "1e39")
    result = subprocess.run(
        [sys.executable, "-m", "jaxtrack", "track", str(campus), "--out", str(tmp_path / "x.txt")],
        capture_output=True,
        text=True,
        cwd=REPO_ROOT,
        timeout=300,
    )
    assert result.returncode == 2 and result.stdout == ""
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "RuntimeWarning" not in result.stderr and "line 101" in result.stderr
    assert not (tmp_path / "x.txt").exists()


@st.composite
def still_targets(draw):
    """A legal, unsuspicious sequence: image sides anywhere in their range (at most 4 times
    wider than high or higher than wide), a frame rate anywhere in its range, and 2 targets of
    5-40% of the image that stand still with high-score detections in every frame."""
    width = draw(st.integers(MIN_IMAGE_SIZE, MAX_IMAGE_SIZE))
    aspect = draw(st.floats(0.25, 4.0))
    height = min(max(round(width * aspect), MIN_IMAGE_SIZE), MAX_IMAGE_SIZE)
    rate = draw(st.sampled_from([MIN_FRAME_RATE, 7.0, 25.0, 240.0, MAX_FRAME_RATE]))
    rows = []
    for target in range(2):
        w = draw(st.floats(0.05, 0.25)) * width
        h = draw(st.floats(0.1, 0.4)) * height
        x = draw(st.floats(0.0, 0.45)) * width + target * width / 2
        y = draw(st.floats(0.0, 0.5)) * height
        rows.append((x, y, max(w, MIN_BOX_SIZE), max(h, MIN_BOX_SIZE)))
    return width, height, rate, rows


@settings(
    max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(scene=still_targets())
def test_tracking_a_valid_sequence_never_gives_an_empty_result(tmp_path_factory, scene):
    width, height, rate, boxes = scene
    folder = tmp_path_factory.mktemp("legal")
    (folder / "det").mkdir()
    frames = 12
    (folder / "seqinfo.ini").write_text(
        f"[Sequence]\nname=legal\nframeRate={rate}\nseqLength={frames}\n"
        f"imWidth={width}\nimHeight={height}\n"
    )
    lines = [
        f"{t},-1,{x:.3f},{y:.3f},{w:.3f},{h:.3f},0.99,-1,-1,-1"
        for t in range(1, frames + 1)
        for x, y, w, h in boxes
    ]
    (folder / "det" / "det.txt").write_text("\n".join(lines) + "\n")
    out = folder / "res.txt"
    assert main(["track", str(folder), "--out", str(out), "--quiet"]) == 0
    result = read_mot_file(out, "res")
    assert len(result) > 0, scene
    assert np.all(np.isfinite(result.boxes))
