"""Fixtures for the metric tests: the 11 MOT15 ground-truth files, read once."""

from __future__ import annotations

import pytest

from jaxtrack.io import read_mot_file, read_seqinfo


@pytest.fixture(scope="session")
def mot15_gt(mot15_root) -> dict:
    """``{sequence: (gt table, seqLength)}`` for every sequence in ../shared/data/mot15."""
    tables = {}
    for folder in sorted(p for p in mot15_root.iterdir() if p.is_dir()):
        seq_length = read_seqinfo(folder / "seqinfo.ini").seq_length
        tables[folder.name] = (
            read_mot_file(folder / "gt" / "gt.txt", "gt", seq_length),
            seq_length,
        )
    assert len(tables) == 11
    return tables
