"""A scratch folder of small inputs for CLI refusal tests, and how to check a refusal.

The workspace holds a benchmark root ``mot/`` with one sequence ``mot/S1`` (TUD-Campus's
``seqinfo.ini``, ``det/det.txt`` and ``gt/gt.txt``, three black 640x480 frames in ``img1/``
and a stand-in ``TUD-Campus.mp4``), an image folder ``frames/`` (three frames), a stand-in
video ``video.avi``, a tracker configuration ``run.config.json``, a stand-in context ``ctx.npz``,
clutter labels ``labels.json``, a plain file ``file.txt``, an empty folder ``folder/``, a
symlink ``link.txt`` to the sequence's ``seqinfo.ini`` and a hard link ``hard.txt`` to its
detections. A refused run must leave every file of the workspace as it was and add none.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import cv2
import numpy as np

from jaxtrack.cli import main
from tests.data import MOT15_ROOT

#: The sequence the workspace's ``mot/S1`` copies.
SOURCE = "TUD-Campus"


def build_workspace(root: Path) -> dict[str, str]:
    """Writes the workspace into ``root``; returns the ``str.format`` fields of its paths."""
    source = MOT15_ROOT / SOURCE
    sequence = root / "mot" / "S1"
    for name in ("seqinfo.ini", "det/det.txt", "gt/gt.txt"):
        (sequence / name).parent.mkdir(parents=True, exist_ok=True)
        (sequence / name).write_bytes((source / name).read_bytes())
    black = np.zeros((480, 640, 3), np.uint8)
    for folder in (sequence / "img1", root / "frames"):
        folder.mkdir()
        for k in range(1, 4):
            cv2.imwrite(str(folder / f"{k:06d}.png"), black)
    (sequence / f"{SOURCE}.mp4").write_bytes(b"not really a video")
    (root / "video.avi").write_bytes(b"not really a video")
    (root / "run.config.json").write_text(json.dumps({"num_particles": 64}))
    (root / "ctx.npz").write_bytes(b"not really a context")
    (root / "labels.json").write_text("{}")
    (root / "file.txt").write_text("a file\n")
    (root / "folder").mkdir()
    (root / "link.txt").symlink_to(sequence / "seqinfo.ini")
    os.link(sequence / "det" / "det.txt", root / "hard.txt")
    return {
        "tmp": str(root),
        "mot": str(root / "mot"),
        "seq": str(sequence),
        "frames": str(root / "frames"),
        "video": str(root / "video.avi"),
        "config": str(root / "run.config.json"),
        "ctx": str(root / "ctx.npz"),
    }


def snapshot(root: Path) -> dict[str, str]:
    """Every path under ``root`` with its content's hash (``"folder"`` for a folder)."""
    return {
        str(path.relative_to(root)): (
            hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else "folder"
        )
        for path in sorted(root.rglob("*"))
    }


def run_refused(capsys, root: Path, argv: list[str]) -> str:
    """Runs ``jaxtrack argv`` in-process; asserts exit 2 with one error line and no traceback,
    and that nothing under ``root`` changed or appeared. Returns the error line."""
    before = snapshot(root)
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2, err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"jaxtrack {argv[0]}: error: "), lines[0]
    assert snapshot(root) == before
    return lines[0]
