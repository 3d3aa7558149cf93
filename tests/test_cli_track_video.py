"""``jaxtrack track-video``: one synthetic walker is one track; annotations; bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.io import read_mot_file
from jaxtrack.io.video import id_colour
from tests.synthetic_video import NUM_FRAMES, person_box, write_synthetic_folder


@pytest.fixture(scope="module")
def synthetic_folder(tmp_path_factory):
    return write_synthetic_folder(tmp_path_factory.mktemp("video") / "img1")


def test_video_to_one_track_with_annotated_frames(synthetic_folder, tmp_path, capsys):
    det = tmp_path / "det.txt"
    out = tmp_path / "res.txt"
    frames_dir = tmp_path / "annotated"
    code = main(
        [
            "track-video", str(synthetic_folder), "--no-split", "--save-detections", str(det),
            "--fps", "7", "--out", str(out), "--annotate", str(frames_dir), "--trail", "5",
        ]
    )  # fmt: skip
    assert code == 0
    assert len(read_mot_file(det, "det", NUM_FRAMES)) == NUM_FRAMES  # one walker per frame
    result = read_mot_file(out, "det", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1  # one walker, one identity
    assert len(result) >= NUM_FRAMES - 5
    truth = np.array([person_box(k) for k in result.frames], float)
    centre_error = np.abs(
        result.boxes[:, 0] + result.boxes[:, 2] / 2 - truth[:, 0] - truth[:, 2] / 2
    )
    assert np.median(centre_error) < 3.0
    assert sorted(p.name for p in frames_dir.iterdir()) == [
        f"{k:06d}.png" for k in range(1, NUM_FRAMES + 1)
    ]
    # the last frame shows the track's box in its id colour (left edge, mid-height)
    last = result.select(result.frames == result.frames.max())
    image = cv2.cvtColor(
        cv2.imread(str(frames_dir / f"{last.frames[0]:06d}.png")), cv2.COLOR_BGR2RGB
    )
    x, y, _, h = last.boxes[0]
    assert tuple(image[round(y + h / 2), round(x)]) == id_colour(int(last.ids[0]))
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["detector"] == "horprasert" and used["fps"] == 7.0 and used["variant"] == "UM"
    assert "1 tracks" in capsys.readouterr().out


def test_corrupt_video_exits_2(tmp_path, capsys):
    bad = tmp_path / "broken.mp4"
    bad.write_bytes(b"\x00" * 1000)
    assert main(["track-video", str(bad), "--out", str(tmp_path / "r.txt")]) == 2
    err = capsys.readouterr().err
    assert "jaxtrack track-video: error:" in err and str(bad) in err and "Traceback" not in err


def test_learn_context_video_needs_detections(data_root, tmp_path, capsys):
    video = data_root / "video" / "vtest.avi"
    code = main(["learn-context", str(video), "--out", str(tmp_path / "c.npz")])
    assert code == 2
    assert "--detections" in capsys.readouterr().err
