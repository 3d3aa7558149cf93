"""``jaxtrack label-clutter``: help, headless exit status 2, input errors, and the wiring."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from jaxtrack.cli import main
from jaxtrack.commands import label_clutter as label_clutter_command
from jaxtrack.context.clutter_labels import choose_frames, load_clutter_labels
from jaxtrack.plot import label_tool


@pytest.fixture(scope="module")
def pets(mot15_root):
    return str(mot15_root / "PETS09-S2L1")


@pytest.fixture(scope="module")
def vtest(data_root):
    return str(data_root / "video" / "vtest.avi")


def run_cli(capsys, *argv) -> tuple[int, str, str]:
    status = main(["label-clutter", *map(str, argv)])
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_help_explains_clicks_and_keys(capsys):
    with pytest.raises(SystemExit) as info:
        main(["label-clutter", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for needle in ("left click", "next frame", "previous frame", "save and close", "--resume"):
        assert needle in text
    with pytest.raises(SystemExit):
        main(["--help"])
    assert "label-clutter" in capsys.readouterr().out


def test_headless_backend_exits_2_with_message(capsys, tmp_path, pets, vtest):
    out = tmp_path / "labels.json"
    status, _, err = run_cli(
        capsys, pets, "--video", vtest, "--frames", "1:397", "--out", out, "--backend", "agg"
    )
    assert status == 2
    assert err.startswith("jaxtrack label-clutter: error: no interactive matplotlib backend")
    assert "--backend" in err and "DISPLAY" in err
    assert not out.exists()


def test_unloadable_backend_exits_2(capsys, tmp_path, pets, monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    status, _, err = run_cli(
        capsys, pets, "--frames", "1:20", "--out", tmp_path / "l.json", "--backend", "tkagg"
    )
    assert status == 2
    assert "cannot use the matplotlib backend 'tkagg'" in err and "DISPLAY" in err


def test_default_backend_in_a_headless_process_exits_2(tmp_path, pets, vtest):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    env["MPLBACKEND"] = ""
    out = tmp_path / "labels.json"
    command = [sys.executable, "-m", "jaxtrack", "label-clutter", pets, "--video", vtest]
    result = subprocess.run(
        [*command, "--frames", "1:397", "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 2, result.stderr
    assert "no interactive matplotlib backend" in result.stderr
    assert "Traceback" not in result.stderr
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        ([], "--frames A:B is required"),
        (["--frames", "1:900"], "frame span 1:900 must satisfy"),
        (["--frames", "1:20", "--num-frames", "0"], "argument --num-frames: value must lie in"),
        (["--frames", "1:20", "--video", "{tmp}/missing.avi"], "missing.avi: video file"),
        (["--frames", "1:20", "--video", "{tud}"], "is 640x480 but seqinfo.ini says 768x576"),
        (["--frames", "1:20", "--resume", "{tmp}/none.json"], "drop --frames"),
        (["--resume", "{tmp}/none.json"], "none.json: labels file not found"),
    ],
)
def test_input_errors_exit_2(capsys, tmp_path, pets, mot15_root, extra, message):
    tud = mot15_root / "TUD-Campus" / "TUD-Campus.mp4"
    extra = [arg.format(tmp=tmp_path, tud=tud) for arg in extra]
    status, _, err = run_cli(capsys, pets, "--out", tmp_path / "l.json", *extra)
    assert status == 2
    assert message in err


def test_existing_out_and_bad_resume_files(capsys, tmp_path, pets, mot15_root):
    out = tmp_path / "labels.json"
    out.write_text('{\n  "format_version": 1,\n  "sequence": PETS\n}\n')
    status, _, err = run_cli(capsys, pets, "--frames", "1:20", "--out", out)
    assert status == 2 and f"{out} exists; continue it with --resume" in err
    status, _, err = run_cli(capsys, pets, "--resume", out, "--out", out)
    assert status == 2 and f"{out}, line 3: not valid JSON" in err
    other = tmp_path / "other.json"
    other.write_text(
        json.dumps(
            {
                "format_version": 1,
                "sequence": "TUD-Campus",
                "image_width": 640,
                "image_height": 480,
                "labelled_frames": [1],
                "pending_frames": [2],
                "clutter": [],
            }
        )
    )
    status, _, err = run_cli(capsys, pets, "--resume", other, "--out", other)
    assert status == 2 and "labels TUD-Campus at 640x480" in err
    short_video = mot15_root / "TUD-Campus" / "TUD-Campus.mp4"  # 71 frames
    status, _, err = run_cli(
        capsys,
        mot15_root / "TUD-Stadtmitte",
        "--frames",
        "100:179",
        "--num-frames",
        "80",
        "--video",
        short_video,
        "--out",
        tmp_path / "new.json",
    )
    assert status == 2 and "has 71 frames but frame 179 is to be shown" in err


def headless_session(calls, clicks_per_frame: int, quit_after: int):
    """A stand-in for label_interactively: an Agg labeller clicking boxes, then ``q``."""

    def fake(det_table, frames, out_path, **kwargs):
        calls.append({"frames": np.asarray(frames), **kwargs})
        figure = Figure()
        FigureCanvasAgg(figure)
        options = {k: v for k, v in kwargs.items() if k != "backend"}
        labeller = label_tool.ClutterLabeller(figure, det_table, frames, out_path, **options)
        for _ in range(quit_after):
            for row in labeller.rows[:clicks_per_frame]:
                labeller.toggle(int(row))
            labeller.show(min(labeller.index + 1, len(labeller.frames) - 1))
        calls[-1]["shown"] = labeller.image.get_array()
        labeller.close()
        return labeller.labels()

    return fake


def test_session_wiring_and_resume(capsys, tmp_path, mot15_root, monkeypatch):
    sequence_dir = mot15_root / "TUD-Stadtmitte"
    out = tmp_path / "tud.json"
    calls: list[dict] = []
    # The command's own reference to the session (the command module imports it by name).
    monkeypatch.setattr(label_clutter_command, "label_interactively", headless_session(calls, 1, 2))
    status, printed, _ = run_cli(
        capsys, sequence_dir, "--frames", "1:90", "--num-frames", "5", "--seed", "7", "--out", out
    )
    assert status == 0
    expected = choose_frames(1, 90, 5, seed=7)
    np.testing.assert_array_equal(calls[0]["frames"], expected)
    assert calls[0]["sequence"] == "TUD-Stadtmitte" and calls[0]["image_size"] == (640, 480)
    reader = calls[0]["frame_source"].__self__  # found SEQ_DIR/TUD-Stadtmitte.mp4 by itself
    assert reader.path == sequence_dir / "TUD-Stadtmitte.mp4"
    assert calls[0]["shown"].shape == (480, 640, 3) and calls[0]["shown"].std() > 10
    assert calls[0]["resume"] is None and calls[0]["backend"] is None
    labels = load_clutter_labels(out)
    np.testing.assert_array_equal(labels.labelled_frames, expected[:3])
    np.testing.assert_array_equal(labels.pending_frames, expected[3:])
    assert len(labels) == 2  # one box on each of the first two frames
    assert f"{out}: 2 clutter detections on 3 labelled frames (2 still to show)" in printed

    status, printed, _ = run_cli(capsys, sequence_dir, "--resume", out, "--out", out)
    assert status == 0
    np.testing.assert_array_equal(calls[1]["frames"], expected)
    assert calls[1]["resume"] is not None
    resumed = load_clutter_labels(out)
    np.testing.assert_array_equal(resumed.labelled_frames, expected)
    assert resumed.pending_frames.size == 0
    assert len(resumed) == 4
    np.testing.assert_array_equal(resumed.boxes[:2], labels.boxes)
