"""The confirming score of a detector, read from its own scores (CMT and Hierarchical).

Not in the papers. The PHD tracker, CMT and the Hierarchical low level confirm a track (a
component) once it has held a detection scoring at least ``confirm_score`` (0.97). A fixed
score means different things for different detectors: 68 % of the PETS09-S2L1 detections
score 0.97 or more, 4.8 % of the synthetic scenes' (whose true detections score 0.8 on
average). :func:`confident_score` lowers the bar to a quantile of the scores the tracker has
seen so far (:func:`count_scores`, a histogram carried in the tracker's state), the same test
for every detector: "among the detector's most confident".

* CMT (session 46): on the development scenes, 720 of CMT's 1,552 dropped boxes lay under a
  component that followed the person but was never confirmed.
* Hierarchical (session 47): on the development scenes a person entering the scene was
  confirmed 16 to 23 frames after their first detection, in the middle of the others, and
  read as a group birth, not an entry (synthetic video seed 2, people 13 and 19).
"""

from __future__ import annotations

import jax.numpy as jnp
from jaxtyping import Array, Float

from jaxtrack.types import Detections

#: Bins of the histogram of detection scores on ``[0, 1]`` that :func:`confident_score`
#: reads (scores outside are counted in the end bins).
SCORE_BINS = 200
#: Detections :func:`confident_score` counts before it reads their quantile.
MIN_SCORES = 100


def init_counts() -> Float[Array, " score_bins"]:
    """An empty histogram (``[SCORE_BINS]`` zeros)."""
    return jnp.zeros((SCORE_BINS,), jnp.float32)


def count_scores(
    counts: Float[Array, " score_bins"], blobs: Detections
) -> Float[Array, " score_bins"]:
    """``counts`` with the frame's detection scores added (the ``mask``ed ones; bins of width
    ``1 / SCORE_BINS`` on ``[0, 1]``; scores outside go to the end bins)."""
    bins = jnp.clip(jnp.floor(blobs.scores * SCORE_BINS), 0, SCORE_BINS - 1).astype(jnp.int32)
    return counts.at[bins].add(blobs.mask.astype(counts.dtype))


def confident_score(
    counts: Float[Array, " score_bins"],
    confirm_score: Float[Array, ""],
    quantile: Float[Array, ""],
) -> Float[Array, ""]:
    """The score from which a detection confirms: ``confirm_score``, or the lower edge of the
    bin that holds the ``quantile`` of the counted scores when that is lower (module
    docstring). With fewer than :data:`MIN_SCORES` detections counted (a quantile of a few
    frames' scores is noise), or ``quantile`` >= 1, ``confirm_score``.
    """
    total = jnp.sum(counts)
    below = jnp.cumsum(counts) < quantile * total
    edge = jnp.sum(below).astype(jnp.float32) / SCORE_BINS
    learned = (total >= MIN_SCORES) & (quantile < 1)
    return jnp.where(learned, jnp.minimum(confirm_score, edge), confirm_score)
