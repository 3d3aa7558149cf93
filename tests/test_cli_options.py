"""An option that would be ignored is an error (issue 14), before any work.

Each refused run exits 2 with one error line that starts with the option, leaves the inputs
as they were and writes nothing (tests/cli_workspace.py).
"""

from __future__ import annotations

import argparse
import json
import shutil

import pytest

from jaxtrack.cli import main
from jaxtrack.commands.arguments import context_variant
from jaxtrack.errors import InputError
from tests.cli_workspace import run_refused

#: ``(arguments, the option named first, why)``; ``{name}`` fields are workspace paths.
IGNORED = [
    # track
    ("track {seq} --out {tmp}/r.txt --variant A2", "--variant", "needs --context"),
    ("track {seq} --out {tmp}/r.txt --tracker kalman --variant A1", "--variant", "needs --context"),
    ("track {seq} --out {tmp}/r.txt --figure-frame 3", "--figure-frame", "needs --figure"),
    ("track {seq} --out {tmp}/r.txt --video {video}", "--video", "needs --figure"),
    ("track {seq} --out {tmp}/r.txt --preset sort", "--preset", "applies to --tracker kalman"),
    (
        "track {seq} --out {tmp}/r.txt --tracker kalman --context {ctx}",
        "--context",
        "applies to the PHD tracker",
    ),
    (
        "track --benchmark {mot} --out {tmp}/res --variant A1",
        "--variant",
        "applies to one sequence, not to --benchmark",
    ),
    (
        "track --benchmark {mot} --out {tmp}/res --figure-frame 2",
        "--figure-frame",
        "applies to one sequence, not to --benchmark",
    ),
    (
        "track --benchmark {mot} --out {tmp}/res --frames 1:5",
        "--frames",
        "applies to one sequence, not to --benchmark",
    ),
    # track-video
    ("track-video {video} --out {tmp}/r.txt --variant A1", "--variant", "needs --context"),
    (
        "track-video {video} --out {tmp}/r.txt --detections {seq}/det/det.txt --method mog2",
        "--method",
        "applies when detecting, not with --detections",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --detections {seq}/det/det.txt --no-split",
        "--no-split",
        "applies when detecting, not with --detections",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --detections {seq}/det/det.txt "
        "--save-detections {tmp}/d.txt",
        "--save-detections",
        "applies when detecting, not with --detections",
    ),
    ("track-video {video} --out {tmp}/r.txt --trail 5", "--trail", "needs --annotate"),
    (
        "track-video {video} --out {tmp}/r.txt --context {ctx} --overlay birth",
        "--overlay",
        "needs --annotate",
    ),
    (
        "track-video {video} --out {tmp}/r.txt --annotate {tmp}/a.mp4 --overlay birth",
        "--overlay",
        "needs --context",
    ),
    # detect
    ("detect {frames} --out {tmp}/d.txt --fps 7", "--fps", "applies to a --preview video"),
    (
        "detect {frames} --out {tmp}/d.txt --fps 7 --preview {tmp}/pngs",
        "--fps",
        "applies to a --preview video",
    ),
    # learn-context
    ("learn-context {seq} --out {tmp}/c.npz --video {video}", "--video", "needs --plot"),
    ("learn-context {seq} --out {tmp}/c.npz --gt {seq}/gt/gt.txt", "--gt", "apply to a video"),
    (
        "learn-context {video} --detections {seq}/det/det.txt --gt {seq}/gt/gt.txt "
        "--clutter-from tracks --out {tmp}/c.npz",
        "--gt",
        "is read only for --birth-from gt or --clutter-from gt",
    ),
    # simulate
    ("simulate --print-config --out {tmp}/s", "--out", "does nothing with --print-config"),
    ("simulate --print-config --name scene", "--name", "does nothing with --print-config"),
    (
        "simulate --print-config --preview-frame 3",
        "--preview-frame",
        "does nothing with --print-config",
    ),
    ("simulate --print-config --seed 2", "--seed", "does nothing with --print-config"),
    # eval
    (
        "eval --gt {seq}/gt/gt.txt --res {seq}/gt/gt.txt --centre-threshold 5 --iou-threshold 0.3",
        "--iou-threshold",
        "is unused with --centre-threshold",
    ),
    # inspect
    ("inspect {tmp}/no-gt --iou 0.3", "--iou", "needs ground truth"),
    # experiments
    (
        "experiment compare-trackers --out {tmp}/c --quick --mot-root {mot}",
        "--mot-root",
        "is not compared with --quick or --no-mot",
    ),
    (
        "experiment compare-trackers --out {tmp}/c --no-mot --mot-root {mot}",
        "--mot-root",
        "is not compared with --quick or --no-mot",
    ),
    (
        "experiment gradient-tuning --out {tmp}/g --no-pets --pets {seq}",
        "--pets",
        "is not used with --no-pets",
    ),
]


@pytest.mark.parametrize(("arguments", "option", "why"), IGNORED)
def test_ignored_option_is_an_error(workspace, tmp_path, capsys, arguments, option, why):
    no_gt = tmp_path / "no-gt"
    shutil.copytree(tmp_path / "mot" / "S1", no_gt)
    shutil.rmtree(no_gt / "gt")
    argv = arguments.format(**workspace).split()
    line = run_refused(capsys, tmp_path, argv)
    assert line.split("error: ", 1)[1].startswith(f"{option} ") and why in line


def test_variant_defaults_to_gm_with_a_context():
    assert context_variant(argparse.Namespace(context="c.npz", variant=None)) == "GM"
    assert context_variant(argparse.Namespace(context="c.npz", variant="A2")) == "A2"
    assert context_variant(argparse.Namespace(context=None, variant=None)) is None
    with pytest.raises(InputError, match="--variant needs --context"):
        context_variant(argparse.Namespace(context=None, variant="GM"))


def test_options_that_are_used_still_work(workspace, capsys):
    seq = workspace["seq"]
    assert main(["inspect", seq, "--frames", "1:5", "--iou", "0.3", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["frames"] == 5
    gt = f"{seq}/gt/gt.txt"
    argv = ["eval", "--gt", gt, "--res", gt, "--frames", "1:5", "--centre-threshold", "5"]
    assert main([*argv, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["MOTA"] == 1.0
    assert main(["simulate", "--print-config", "--num-frames", "12"]) == 0
    assert json.loads(capsys.readouterr().out)["num_frames"] == 12
