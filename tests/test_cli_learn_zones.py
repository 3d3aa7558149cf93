"""``jaxtrack learn-zones``: zones.json, mask and figure; the three sources; bad input."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from jaxtrack import cli
from jaxtrack.context.io import save_context
from jaxtrack.datasets.synthetic import generate_scene, write_scene
from jaxtrack.io.zones import load_zones
from tests.context.zone_scenes import (
    CROSSING_FRAMES,
    CROSSING_SCENE,
    CROSSING_ZONES,
    zone_feet,
)

GOLD = np.array([255, 215, 0])  # matplotlib's "gold": the zone boxes of the figure


@pytest.fixture
def run_cli(monkeypatch, capsys):
    """``jaxtrack learn-zones ARGS`` -> ``(exit code, stdout, stderr)``."""
    monkeypatch.setattr(cli, "COMMANDS", ("learn_zones",))

    def run(*argv):
        code = cli.main(["learn-zones", *map(str, argv)])
        captured = capsys.readouterr()
        return code, captured.out, captured.err

    return run


@pytest.fixture(scope="module")
def crossing():
    return generate_scene(0, CROSSING_SCENE)


@pytest.fixture(scope="module")
def crossing_dir(crossing, tmp_path_factory):
    return write_scene(crossing, tmp_path_factory.mktemp("cli-zones") / "CROSS-0")


def centres(zones: list[dict]) -> np.ndarray:
    return np.array([(z["x"] + z["w"] / 2, z["y"] + z["h"] / 2) for z in zones]).reshape(-1, 2)


def gold_pixels(path) -> np.ndarray:
    image = cv2.cvtColor(cv2.imread(str(path)), cv2.COLOR_BGR2RGB).astype(int)
    return np.all(np.abs(image - GOLD) < 30, axis=-1)


def test_help_explains_sources_zones_and_mask(run_cli, capsys):
    with pytest.raises(SystemExit) as exit_info:
        run_cli("--help")
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    for words in ("--from", "--margin", "--figure", "--video", "convex", "interior",
                  "activity.png", "CTX.npz", "Fusion"):  # fmt: skip
        assert words in text, words


def test_zones_of_a_synthetic_scene_from_gt(run_cli, crossing_dir, tmp_path):
    out = tmp_path / "z.json"
    code, printed, _ = run_cli(crossing_dir, "--from", "gt", "--out", out, "--quiet", "--json")
    assert code == 0
    report = json.loads(printed)
    assert report["frames"] == [1, CROSSING_FRAMES] and report["from"] == "gt"
    assert report["activity_mask"] == str(tmp_path / "z.activity.png")
    found = centres(report["zones"])
    for zone, feet in zip(CROSSING_ZONES, zone_feet(CROSSING_ZONES, CROSSING_SCENE), strict=True):
        assert np.min(np.linalg.norm(found - feet, axis=1)) <= 20.0, zone.name
    loaded = load_zones(out)
    np.testing.assert_allclose(
        centres(report["zones"]), loaded.boxes[:, :2] + loaded.boxes[:, 2:] / 2
    )
    assert loaded.activity.shape == (72, 96) and 0.1 < loaded.activity.mean() < 0.9
    points = report["points"]
    assert 0 < sum(z["entries"] for z in report["zones"]) <= points["starts"]
    assert 0 < sum(z["exits"] for z in report["zones"]) <= points["ends"]


def test_pets09_zones_lie_on_the_image_edges(run_cli, mot15_root, data_root, tmp_path):
    out, figure = tmp_path / "pz.json", tmp_path / "pz.png"
    code, printed, _ = run_cli(
        mot15_root / "PETS09-S2L1", "--video", data_root / "video" / "vtest.avi", "--from", "gt",
        "--out", out, "--figure", figure, "--quiet",
    )  # fmt: skip
    assert code == 0 and f"wrote {out}" in printed and "entries" in printed
    zones = load_zones(out).boxes
    x, y, w, h = zones.T
    # people enter PETS09-S2L1 on the right (most) and the left of the image
    assert len(zones) >= 2
    assert np.all((x <= 2) | (x + w >= 766) | (y <= 2) | (y + h >= 574))
    assert x[0] + w[0] >= 766 and np.any(x <= 2)
    gold = gold_pixels(figure)
    assert gold.shape[1] == 800 and gold.sum() > 500
    columns = np.flatnonzero(gold.any(axis=0))
    assert columns.min() < 100 and columns.max() > 700  # boxes drawn on both sides


def test_zones_from_tracks(run_cli, crossing_dir, tmp_path):
    out = tmp_path / "z.json"
    code, printed, _ = run_cli(
        crossing_dir, "--frames", "1:200", "--out", out, "--seed", 1, "--quiet", "--json"
    )
    assert code == 0
    report = json.loads(printed)
    assert report["from"] == "tracks" and report["frames"] == [1, 200]
    assert report["points"]["starts"] > 0 and load_zones(out).activity.any()


def test_zones_from_a_birth_intensity(run_cli, crossing, crossing_dir, tmp_path):
    context, out, figure = tmp_path / "ctx.npz", tmp_path / "z.json", tmp_path / "z.png"
    save_context(context, crossing.birth_intensity, crossing.clutter_intensity, {"frames": [1, 9]})
    code, printed, _ = run_cli(crossing_dir, "--from", context, "--out", out, "--figure", figure,
                               "--quiet", "--json")  # fmt: skip
    assert code == 0
    report = json.loads(printed)
    assert report["activity_mask"] is None and report["frames"] == [1, 9]
    assert not (tmp_path / "z.activity.png").exists()
    # the zones' mean feet, but for the south box, clipped at the image bottom (3 px)
    feet = zone_feet(CROSSING_ZONES, CROSSING_SCENE)
    np.testing.assert_allclose(centres(report["zones"]), feet, atol=4.0)
    assert [z["share"] for z in report["zones"]] == [0.25] * 4
    assert load_zones(out).activity is None and gold_pixels(figure).sum() > 100


def test_no_zone_is_a_warning(run_cli, mot15_root, tmp_path):
    code, printed, err = run_cli(
        mot15_root / "PETS09-S2L1", "--frames", "1:30", "--from", "gt", "--out",
        tmp_path / "z.json", "--quiet",
    )  # fmt: skip
    assert code == 0 and "0 zones" in printed
    assert "warning: no zone found" in err
    assert json.loads((tmp_path / "z.json").read_text())["zones"] == []


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ("{seq} --out {tmp}/z.json --video {seq}/seqinfo.ini", "--video needs --figure"),
        ("{seq} --out {tmp}/z.json --from {tmp}/nothing.npz", "--from must be tracks, gt or"),
        ("{seq} --out {tmp}/z.json --from {ctx} --frames 1:5", "--frames does not apply"),
        ("{seq} --out {tmp}/z.json --from {ctx} --margin 2", "--margin does not apply"),
        ("{seq} --out {tmp}/z.json --from gt --seed 3", "--seed seeds the tracker run"),
        ("{seq} --out {seq}/gt/gt.txt --from gt", "--out"),
        ("{seq} --out {tmp}/z.json --figure {tmp}/z.xyz --from gt", "writes no .xyz figures"),
        ("{seq} --out {tmp}/z.json --margin -1 --from gt", "--margin"),
        ("{tmp}/none --out {tmp}/z.json --from gt", "sequence folder not found"),
        ("{seq} --out {tmp}/z.json --from gt --frames 1:3", "no trajectory starts or ends"),
        ("{nogt} --out {tmp}/z.json --from gt", "no ground truth"),
    ],
)
def test_bad_input_exits_2_with_a_message(run_cli, crossing, crossing_dir, tmp_path, argv,
                                          message):  # fmt: skip
    context = tmp_path / "ctx.npz"
    save_context(context, crossing.birth_intensity, crossing.clutter_intensity)
    no_gt = tmp_path / "nogt"
    for name in ("seqinfo.ini", "det/det.txt"):
        (no_gt / name).parent.mkdir(parents=True, exist_ok=True)
        (no_gt / name).write_bytes((crossing_dir / name).read_bytes())
    fields = {"seq": crossing_dir, "tmp": tmp_path, "ctx": context, "nogt": no_gt}
    code, _, err = run_cli(*argv.format(**fields).split())
    assert code == 2 and message in err, err
    assert not (tmp_path / "z.json").exists()
