"""``jaxtrack track-video``: one synthetic walker is one track (PHD, CMT); annotations (CMT's
particles in their motion conditions' colours); bad input and refused option combinations."""

from __future__ import annotations

import json
import re

import cv2
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.cli import main
from jaxtrack.detect.sequence import video_sequence
from jaxtrack.errors import InputError
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt_conditions import EXIT, MERGE, NORMAL, SPLIT
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import read_mot_file
from jaxtrack.io.video import VideoReader, id_colour
from jaxtrack.plot.cmt_frames import (
    CONDITION_COLOURS,
    LEGEND_MARGIN,
    LEGEND_ROW,
    LEGEND_WIDTH,
    OUTLINE_COLOUR,
    PARTICLE_RADIUS,
    draw_condition_legend,
    draw_particles,
)
from jaxtrack.types import FrameInputs, SequenceInfo
from tests.synthetic_video import NUM_FRAMES, PERSON, SIZE, person_box, write_synthetic_folder


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


# --- --tracker cmt: particles coloured by motion condition ---------------------------------

CMT_FRAMES = 20
#: A small CMT (few slots and particles) keeps the compile and the run short.
SMALL_CMT = {"max_components": 4, "particles_per_component": 16}


def write_truth_detections(path, num_frames: int) -> None:
    """The synthetic walker's true box as the one detection of each frame."""
    rows = [
        f"{k},-1,{','.join(map(str, person_box(k)))},1,-1,-1,-1" for k in range(1, num_frames + 1)
    ]
    path.write_text("\n".join(rows) + "\n")


def cmt_reference_run(folder, det_path, seed: int):
    """CMT's per-frame infos on the first frames, unchunked, on frames held in memory: an
    oracle independent of the streamed run of the CLI."""
    info = SequenceInfo("synthetic", NUM_FRAMES, SIZE[0], SIZE[1], 7.0)
    seq = video_sequence(folder, read_mot_file(det_path, "det", info=info), (1, CMT_FRAMES), info)
    config = CMTConfig(variant="cmt", **SMALL_CMT)
    filt, params = build_tracker(config, seq.info, None)
    with VideoReader(folder) as reader:
        images = np.stack([reader.read(k) for k in range(1, CMT_FRAMES + 1)])
    inputs = FrameInputs(seq.detections, jnp.asarray(images))
    _, outputs = run(filt, jax.random.PRNGKey(seed), params, inputs)
    return jax.device_get(outputs)


def test_cmt_annotation_draws_particles_in_condition_colours(synthetic_folder, tmp_path, capsys):
    det = tmp_path / "det.txt"
    write_truth_detections(det, NUM_FRAMES)
    config = tmp_path / "cmt.json"
    config.write_text(json.dumps(SMALL_CMT))
    zones = tmp_path / "zones.json"
    zones.write_text(
        json.dumps(
            {"format_version": 1, "image_width": SIZE[0], "image_height": SIZE[1],
             "zones": [], "activity_mask": None}
        )
    )  # fmt: skip
    out = tmp_path / "res.txt"
    frames_dir = tmp_path / "annotated"
    code = main(
        [
            "track-video", str(synthetic_folder), "--frames", f"1:{CMT_FRAMES}", "--fps", "7",
            "--detections", str(det), "--tracker", "cmt", "--variant", "cmt", "--config",
            str(config), "--zones", str(zones), "--out", str(out), "--annotate", str(frames_dir),
            "--quiet",
        ]
    )  # fmt: skip
    assert code == 0
    result = read_mot_file(out, "det", NUM_FRAMES)
    assert len(set(result.ids.tolist())) == 1 and len(result) >= CMT_FRAMES - 5
    truth = np.array([person_box(k) for k in result.frames], float)
    assert np.median(np.abs(result.boxes[:, 0] - truth[:, 0])) < 6.0
    used = json.loads((tmp_path / "res.config.json").read_text())
    assert used["tracker"] == "cmt" and used["variant"] == "cmt"
    assert used["max_components"] == 4 and used["zones"] == f"zones from {zones}"
    assert sorted(p.name for p in frames_dir.iterdir()) == [
        f"{k:06d}.png" for k in range(1, CMT_FRAMES + 1)
    ]
    printed = capsys.readouterr()
    assert "1 tracks" in printed.out and f"zones from {zones}" in printed.err

    infos = cmt_reference_run(synthetic_folder, det, seed=0)
    legend_left = SIZE[0] - LEGEND_MARGIN - LEGEND_WIDTH
    legend_bottom = LEGEND_MARGIN + LEGEND_ROW * len(CONDITION_COLOURS) + 4
    checked, near_walker = 0, []
    for t in range(CMT_FRAMES):
        image = cv2.cvtColor(cv2.imread(str(frames_dir / f"{t + 1:06d}.png")), cv2.COLOR_BGR2RGB)
        alive = infos.alive[t]
        centres = infos.particles[t][alive][:, :, [0, 2]].reshape(-1, 2)
        conditions = infos.conditions[t][alive].reshape(-1)
        walker = np.array(person_box(t + 1), float)
        if alive.any():
            near_walker.append(
                np.median(np.linalg.norm(centres - walker[:2] - walker[2:] / 2, axis=1))
            )
        pixels = np.round(centres).astype(int)
        for (x, y), condition in zip(pixels.tolist(), conditions.tolist(), strict=True):
            if not (0 <= x < SIZE[0] and 0 <= y < SIZE[1]):
                continue
            if x >= legend_left - PARTICLE_RADIUS and y <= legend_bottom + PARTICLE_RADIUS:
                continue
            # a dot of another condition reaching this pixel may cover it: skip those
            reach = np.linalg.norm(pixels - (x, y), axis=1) <= PARTICLE_RADIUS + 0.5
            if set(conditions[reach].tolist()) != {condition}:
                continue
            assert tuple(image[y, x]) == CONDITION_COLOURS[condition][0], (t, x, y)
            checked += 1
    assert checked >= CMT_FRAMES * 8  # most of the 16 particles of the walker, every frame
    # the particles drawn are the walker's: they lag it while the velocity is learned
    assert not infos.alive[0].any() and infos.alive[1:].any(axis=1).all()  # born in frame 1
    assert max(near_walker) < PERSON[1] / 2 and np.median(near_walker) < 6.0


def test_draw_particles_against_a_pixel_oracle():
    image = np.full((40, 60, 3), 7, np.uint8)
    # slot 0: normal and split; slot 1: merge and exit; slot 2 dead (never drawn)
    centres = np.array(
        [[[5.0, 5.0], [15.2, 5.4]], [[25.0, 20.0], [35.0, 30.0]], [[50.0, 20.0], [50.0, 30.0]]]
    )
    conditions = np.array([[NORMAL, SPLIT], [MERGE, EXIT], [NORMAL, EXIT]])
    alive = np.array([True, True, False])
    out = draw_particles(image, centres, conditions, alive)
    assert np.array_equal(image, np.full((40, 60, 3), 7, np.uint8))  # not modified
    for (x, y), condition in zip(
        centres[:2].reshape(-1, 2), conditions[:2].reshape(-1), strict=True
    ):
        x, y = round(x), round(y)
        colour = CONDITION_COLOURS[int(condition)][0]
        assert tuple(out[y, x]) == colour
        assert np.all(out[y - 1 : y + 2, x - 1 : x + 2] == colour)  # a dot, not a point
    # the drawn pixels are the discs of radius PARTICLE_RADIUS around the living particles,
    # outlined by a ring one pixel wide
    rows, cols = np.mgrid[:40, :60]
    discs, rings = np.zeros((40, 60), bool), np.zeros((40, 60), bool)
    for x, y in np.round(centres[:2].reshape(-1, 2)):
        discs |= np.hypot(cols - x, rows - y) <= PARTICLE_RADIUS
        rings |= np.hypot(cols - x, rows - y) <= PARTICLE_RADIUS + 1
    rings &= ~discs
    assert np.array_equal(np.any(out != 7, axis=-1), discs | rings)
    assert np.all(out[rings] == OUTLINE_COLOUR)
    # an exit particle on top of a normal one: the rare condition is drawn last
    both = draw_particles(
        image, np.array([[[9.0, 9.0], [9.0, 9.0]]]), np.array([[EXIT, NORMAL]]), np.array([True])
    )
    assert tuple(both[9, 9]) == CONDITION_COLOURS[EXIT][0]
    # the outlines lie under every dot: a neighbour's ring does not cut into a dot
    pair = draw_particles(
        image, np.array([[[9.0, 9.0], [13.0, 9.0]]]), np.array([[NORMAL, EXIT]]), np.array([True])
    )
    assert tuple(pair[9, 10]) == CONDITION_COLOURS[NORMAL][0]  # in the exit dot's ring
    assert tuple(pair[9, 12]) == CONDITION_COLOURS[EXIT][0]  # in the normal dot's ring
    assert tuple(pair[9, 16]) == OUTLINE_COLOUR


@pytest.mark.parametrize(
    ("centres", "conditions", "message"),
    [
        ([[[1.0, 1.0]]], [[4]], "conditions [4] have no colour"),
        ([[[np.nan, 1.0]]], [[NORMAL]], "non-finite"),
    ],
)
def test_draw_particles_refuses_bad_particles(centres, conditions, message):
    with pytest.raises(InputError, match=re.escape(message)):
        draw_particles(
            np.zeros((8, 8, 3), np.uint8), np.array(centres), np.array(conditions), np.array([True])
        )


def test_condition_legend_in_the_top_right_corner():
    image = np.zeros((120, 240, 3), np.uint8)
    out = draw_condition_legend(image)
    left = 240 - LEGEND_MARGIN - LEGEND_WIDTH
    bottom = LEGEND_MARGIN + LEGEND_ROW * len(CONDITION_COLOURS) + 4
    corner = out[: bottom + 1, left:]
    for colour, _ in CONDITION_COLOURS.values():
        assert np.all(corner == colour, axis=-1).sum() >= 20  # each condition's dot
    changed = np.any(out != 0, axis=-1)
    assert changed[: bottom + 1, left : 240 - LEGEND_MARGIN + 1].mean() > 0.9  # the box
    changed[: bottom + 1, left : 240 - LEGEND_MARGIN + 1] = False
    assert not changed.any()  # nothing outside it


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--tracker", "cmt", "--context", "c.npz"], "--context applies to the PHD tracker"),
        (
            ["--tracker", "cmt", "--annotate", "a", "--overlay", "birth"],
            "--overlay applies to the PHD tracker",
        ),
        (["--zones", "z.json"], "--zones applies to --tracker cmt, not to phd"),
        (["--tracker", "kalman", "--zones", "z.json"], "--zones applies to --tracker cmt"),
        (["--variant", "mtb"], "--variant mtb applies to --tracker cmt"),
        (["--tracker", "cmt", "--variant", "A1"], "A1 is a PHD context variant"),
        (["--tracker", "kalman", "--variant", "GM"], "--variant applies to the PHD tracker"),
        (["--tracker", "cmt", "--overlay", "birth"], "--overlay needs --annotate"),
    ],
)
def test_refused_tracker_options_exit_2(synthetic_folder, tmp_path, capsys, options, message):
    out = tmp_path / "r.txt"
    assert main(["track-video", str(synthetic_folder), "--out", str(out), *options]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err
    assert not out.exists()


def test_help_explains_the_cmt_tracker(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["track-video", "--help"])
    assert exit_info.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "--tracker cmt runs contextual mixture tracking" in text
    assert "normal cyan, split yellow, merge magenta, exit orange-red" in text
    assert "--zones ZONES.json" in text
