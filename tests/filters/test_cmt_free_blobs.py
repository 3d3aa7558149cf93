"""CMT's free-blob births (``CMTConfig.free_blob_frames``).

Oracles: the free-blob runs against a NumPy loop, hand-built components for the forced
births and the separation test, and a drawn scene in which a second target steps out from
beside a tracked one (the paper's dispelling rule keeps it unborn while the tracked
component's particles explain its blob).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.boxes import iou_matrix
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt import FREE_BLOB_IOU, SEPARATION_IOU, FreeBlobs, _crowded, free_runs
from jaxtrack.filters.cmt_tracker import CMTConfig, build_cmt, cmt_params
from jaxtrack.filters.mixture_components import add_component, add_unexplained
from jaxtrack.filters.mixture_state import init_mixture
from jaxtrack.types import Detections
from tests.filters.test_cmt import COLOURS, INFO, SMALL, scene


def test_free_runs_match_a_numpy_loop():
    rng = np.random.default_rng(0)
    slots, num_blobs = 4, 6
    previous = rng.uniform(0, 100, (slots, 2))
    free = FreeBlobs(
        boxes=jnp.asarray(np.hstack([previous, np.full((slots, 2), 20.0)]), jnp.float32),
        runs=jnp.asarray([3, 0, 1, 5], jnp.int32),
    )
    # Blobs: near copies of the previous free blobs (some shifted past the IoU line), and new.
    centres = np.vstack([previous + rng.normal(0, 3, (slots, 2)), rng.uniform(0, 100, (2, 2))])
    centres[2] += 12.0  # slot 2's continuation moved too far
    boxes = np.hstack([centres, np.full((num_blobs, 2), 20.0)])
    mask = np.array([True, True, True, True, True, False])
    owner = np.array([-1, -1, -1, 2, -1, -1])
    blobs = Detections(jnp.asarray(boxes, jnp.float32), jnp.ones(num_blobs), jnp.asarray(mask))
    kept, runs = free_runs(free, blobs, jnp.asarray(owner, jnp.int32))

    overlap = iou_matrix(boxes, np.asarray(free.boxes, np.float64))
    expected = np.zeros(num_blobs, int)
    for b in range(num_blobs):
        if not mask[b] or owner[b] >= 0:
            continue
        longest = 0
        for p in range(slots):
            if int(free.runs[p]) > 0 and overlap[b, p] > FREE_BLOB_IOU:
                longest = max(longest, int(free.runs[p]))
        expected[b] = longest + 1
    assert np.asarray(runs).tolist() == expected.tolist()
    assert expected.tolist()[:3] == [4, 1, 1]  # the continued run, a dead slot, a moved blob
    # The kept slots: the longest runs with their boxes.
    order = np.argsort(-expected, kind="stable")[:slots]
    assert sorted(np.asarray(kept.runs).tolist()) == sorted(expected[order].tolist())
    for run_, box in zip(np.asarray(kept.runs), np.asarray(kept.boxes), strict=True):
        if run_ > 0:
            b = int(np.argmin(np.abs(boxes - box).sum(axis=1)))
            assert expected[b] == run_


def test_a_forced_blob_starts_a_component_that_an_explained_one_would_not():
    params = cmt_params(CMTConfig()).mixture
    state = init_mixture(jax.random.PRNGKey(0), params, 4, 16)
    state, _ = add_component(jax.random.PRNGKey(1), state, jnp.array([50.0, 50, 20, 50]), params)
    near = jnp.array([[52.0, 50, 20, 50], [300.0, 50, 20, 50]])  # explained / unexplained
    blobs = Detections(near, jnp.ones(2), jnp.array([True, True]))
    plain, _ = add_unexplained(jax.random.PRNGKey(2), state, blobs, params)
    assert int(plain.alive.sum()) == 2  # only the far blob starts one
    forced, _ = add_unexplained(
        jax.random.PRNGKey(2), state, blobs, params, forced=jnp.array([True, False])
    )
    assert int(forced.alive.sum()) == 3


def test_crowded_is_an_overlap_with_an_older_component():
    def est(x):
        return [x + 10.0, 0.0, 60.0, 0.0, 20.0, 40.0]  # centre x, vx, centre y, vy, w, h

    estimates = jnp.asarray([est(0), est(15), est(200), est(5)], jnp.float32)
    ids = jnp.asarray([4, 7, 9, 2], jnp.int32)
    alive = jnp.array([True, True, True, False])
    got = np.asarray(_crowded(estimates, alive, ids)).tolist()
    boxes = np.array([[x, 40.0, 20.0, 40.0] for x in (0, 15, 200, 5)])
    overlap = iou_matrix(boxes, boxes)
    assert overlap[1, 0] > SEPARATION_IOU  # 5 px of 20 overlap: IoU 0.14
    assert got == [False, True, False, False]  # the dead slot 3 (id 2) crowds no one


def beside(num_frames=30, start=4):
    """Target A walks right at 1 px/frame; target B appears 10 px to its right at ``start``
    and walks right at 2 px/frame, pulling away from it."""
    truth = []
    for t in range(num_frames):
        a = (40.0 + t, 40.0, 16.0, 36.0)
        b = (50.0 + t + 2.0 * (t - start), 40.0, 16.0, 36.0)
        truth.append([a] if t < start else [a, b])
    return truth


def first_two(config):
    inputs = scene(beside(), COLOURS)
    filt, params = build_cmt(config, INFO)
    _, info = jax.jit(lambda k, p, i, f=filt: run(f, k, p, i))(
        jax.random.PRNGKey(0), params, inputs
    )
    count = np.asarray(info.candidates.mask).sum(axis=1)
    return int(np.argmax(count >= 2)) if np.any(count >= 2) else None


def test_a_target_stepping_out_beside_a_tracked_one_starts_sooner():
    paper = first_two(CMTConfig(variant="cmt", free_blob_frames=0, **SMALL))
    free = first_two(CMTConfig(variant="cmt", free_blob_frames=2, **SMALL))
    assert free is not None
    assert paper is None or paper >= free + 2  # measured: 9 against 6
    assert free <= 4 + 2 + 1  # B's blob free on frames 4 and 5, a component from frame 6 on


def jumped(num_frames=40, at=10, dy=30.0):
    """One target walking right whose detection jumps ``dy`` px down at ``at`` (out of its
    component's reach, within a box height); it scores 0.99 before and 0.9 after."""
    truth = [
        [(20.0 + 2 * t, 40.0 + (dy if t >= at else 0.0), 16.0, 36.0)] for t in range(num_frames)
    ]
    scores = np.where(np.arange(num_frames)[:, None] < at, 0.99, 0.9) * (np.arange(4) < 1)
    return scene(truth, COLOURS[:1], scores)


@pytest.mark.parametrize("variant", ["mtb", "cmt"])
def test_an_unconfirmed_component_takes_over_the_identity_of_the_one_it_replaced(variant):
    # After the jump a new component follows the target while the old one, unsupported, waits
    # out its misses; the new one's blobs never score 0.97, so only a handover confirms it.
    shown = {}
    for frames in (0, 2):
        config = CMTConfig(variant=variant, free_blob_frames=frames, **SMALL)
        filt, params = build_cmt(config, INFO)
        _, info = run(filt, jax.random.PRNGKey(0), params, jumped())
        mask, ids = np.asarray(info.tracks.mask), np.asarray(info.tracks.ids)
        shown[frames] = [sorted(ids[t][mask[t]].tolist()) for t in range(mask.shape[0])]
    assert shown[0][:10] == shown[2][:10] == [[]] + [[0]] * 9
    assert shown[0][10:] == [[]] * 30  # the paper's tracker: the target is lost for good
    # Handed over: the first identity again, from some frame on (frame 16 under the default
    # appearance term for mtb, 32 for cmt; 24 for both under the pre-session-56 a = 1), and
    # kept to the end.
    after = shown[2][10:]
    first = after.index([0])
    assert after[:first] == [[]] * first and after[first:] == [[0]] * (len(after) - first)
    assert len(after) - first >= 8
