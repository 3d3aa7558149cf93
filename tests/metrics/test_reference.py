"""Published reference scores of ../shared/data/PROVENANCE.md (motmetrics 1.4.0 test suite,
TrackEval 1.3.0 for HOTA) for the reference tracker shipped with the two TUD sequences."""

from __future__ import annotations

import pytest

from jaxtrack.io import read_mot_file, read_seqinfo
from jaxtrack.metrics import evaluate_sequence

#: Copied from PROVENANCE.md (MOTP is the mean IoU of matches).
PUBLISHED = {
    "TUD-Campus": dict(
        MOTA=0.526462, IDF1=0.557659, FP=13, FN=150, IDSW=7, Frag=7, MT=1, PT=6, ML=1,
        MOTP=0.722799, HOTA=0.391397,
    ),
    "TUD-Stadtmitte": dict(
        MOTA=0.564014, IDF1=0.644619, FP=45, FN=452, IDSW=7, Frag=6, MT=5, PT=4, ML=1,
        MOTP=0.654096, HOTA=0.397849,
    ),
}  # fmt: skip


@pytest.mark.parametrize("sequence", sorted(PUBLISHED))
def test_published_reference_scores(mot15_root, sequence):
    folder = mot15_root / sequence
    seq_length = read_seqinfo(folder / "seqinfo.ini").seq_length
    gt = read_mot_file(folder / "gt" / "gt.txt", "gt", seq_length)
    result = read_mot_file(folder / "ref_tracker_motmetrics.txt", "res", seq_length)
    scores = evaluate_sequence(gt, result, (1, seq_length)).summary()
    for key, expected in PUBLISHED[sequence].items():
        if isinstance(expected, int):
            assert scores[key] == expected, key
        else:
            assert scores[key] == pytest.approx(expected, abs=1e-6), key
