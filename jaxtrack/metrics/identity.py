"""Identity metrics IDF1, IDP, IDR (Ristani et al. 2016), as TrackEval 1.3.0 computes them.

Each gt trajectory is assigned to at most one tracker trajectory for the whole sequence, the
assignment maximising the number of identity true positives
``IDTP = sum over assigned (g, k) of #frames where sim(g, k) >= threshold``. TrackEval solves
the equivalent minimum-cost problem on the ``(G + K) x (G + K)`` matrix of Ristani et al.
(cost ``IDFN + IDFP``); since ``IDFN + IDFP = N_G + N_T - 2 IDTP`` for every assignment, the
optimum is the same and is found here on the ``G x K`` matrix of match counts directly.

``IDFN = N_G - IDTP``, ``IDFP = N_T - IDTP`` (``N_G``, ``N_T``: gt and tracker boxes),
``IDP = IDTP / (IDTP + IDFP)``, ``IDR = IDTP / (IDTP + IDFN)``,
``IDF1 = IDTP / (IDTP + (IDFP + IDFN) / 2)``; denominators use ``max(1, .)``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from jaxtrack.metrics.preprocess import SequenceData

#: Fields summed when sequences are combined.
ADDITIVE_FIELDS = ("IDTP", "IDFN", "IDFP")


def identity_fields(data: SequenceData, threshold: float = 0.5) -> dict:
    """Identity counts of one sequence.

    Args:
        data: the scored boxes.
        threshold: a frame counts for ``(g, k)`` when ``sim >= threshold`` (no tolerance,
            as in TrackEval).

    Returns:
        ``IDTP, IDFN, IDFP`` (ints).
    """
    num_gt_rows, num_tracker_rows = data.num_rows
    valid = data.similarity >= threshold
    gt_id = data.gt_id[data.pairs.gt_row[valid]]
    tracker_id = data.tracker_id[data.pairs.tracker_row[valid]]
    rows, gt_index = np.unique(gt_id, return_inverse=True)
    cols, tracker_index = np.unique(tracker_id, return_inverse=True)
    counts = np.bincount(
        gt_index * cols.size + tracker_index, minlength=rows.size * cols.size
    ).reshape(rows.size, cols.size)
    assigned_rows, assigned_cols = linear_sum_assignment(counts, maximize=True)
    idtp = int(counts[assigned_rows, assigned_cols].sum())
    return {"IDTP": idtp, "IDFN": num_gt_rows - idtp, "IDFP": num_tracker_rows - idtp}


def identity_scores(fields: dict) -> dict:
    """``IDF1, IDP, IDR`` from (summed) identity counts."""
    idtp, idfn, idfp = fields["IDTP"], fields["IDFN"], fields["IDFP"]
    return {
        "IDF1": idtp / max(1.0, idtp + 0.5 * idfp + 0.5 * idfn),
        "IDP": idtp / max(1.0, idtp + idfp),
        "IDR": idtp / max(1.0, idtp + idfn),
    }
