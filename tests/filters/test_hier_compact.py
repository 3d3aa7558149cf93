"""Histograms of the live boxes only (``live_box_histograms``), and the tracker that uses them.

Oracles: :func:`~jaxtrack.filters.hier_appearance.box_histograms` of every box (itself
checked against a NumPy reference in ``test_hier_appearance.py``): the live boxes' histograms
must be equal to it bit for bit, the others zero; and the full tracker with every box's
histograms computed (the step before compaction), whose per-frame outputs must be equal.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.errors import InputError
from jaxtrack.filters import hierarchical
from jaxtrack.filters.base import run
from jaxtrack.filters.hier_appearance import (
    NUM_BINS,
    NUM_FEATURES,
    box_histograms,
    bucket_sizes,
    live_box_histograms,
    smallest_bucket,
)
from jaxtrack.filters.hierarchical_tracker import HierarchicalConfig, build_hierarchical
from tests.filters.test_cmt import INFO
from tests.filters.test_hierarchical import BACKGROUND, occlusion_scene

PATCH = (6, 4)
SLOTS = 40  # buckets 8, 16, 32, 40
IMAGE = np.random.default_rng(0).integers(0, 256, (48, 64, 3), dtype=np.uint8)
_live = jax.jit(live_box_histograms, static_argnames="patch_shape")


def _boxes(seed: int, count: int = SLOTS) -> np.ndarray:
    """Boxes mostly inside the 64 x 48 image, some across its edges, one wholly outside."""
    rng = np.random.default_rng(seed)
    corner = rng.uniform(-10.0, 60.0, (count, 2))
    size = rng.uniform(4.0, 30.0, (count, 2))
    boxes = np.concatenate([corner, size], axis=1).astype(np.float32)
    boxes[count // 2] = (100.0, 100.0, 10.0, 10.0)
    return boxes


def _alive(seed: int, count: int, num_slots: int = SLOTS) -> np.ndarray:
    """``count`` live slots at random places."""
    alive = np.zeros(num_slots, bool)
    alive[np.random.default_rng(seed).permutation(num_slots)[:count]] = True
    return alive


def _check(result, image, boxes, alive):
    """The oracle: every box's histograms on the live slots (exactly), zeros elsewhere."""
    expected = np.asarray(box_histograms(jnp.asarray(image), jnp.asarray(boxes), PATCH))
    result = np.asarray(result)
    assert result.shape == (len(boxes), NUM_FEATURES, NUM_BINS)
    np.testing.assert_array_equal(result[alive], expected[alive])
    assert not np.any(result[~alive])


def test_bucket_sizes_double_up_to_the_slots():
    assert bucket_sizes(64) == (8, 16, 32, 64)
    assert bucket_sizes(40) == (8, 16, 32, 40)
    assert bucket_sizes(16) == (8, 16)
    assert bucket_sizes(9) == (8, 9)
    assert bucket_sizes(8) == (8,)
    assert bucket_sizes(3) == (3,)


def test_the_smallest_bucket_holding_the_count_is_chosen():
    sizes = bucket_sizes(40)
    chosen = jax.jit(jax.vmap(lambda c: smallest_bucket(c, sizes)))(jnp.arange(41))
    for count, index in enumerate(np.asarray(chosen)):
        assert sizes[index] >= count
        assert index == 0 or sizes[index - 1] < count
    assert int(smallest_bucket(jnp.int32(3), (5,))) == 0  # one bucket


# Counts on both sides of every bucket edge, none and all.
@pytest.mark.parametrize("count", [0, 1, 7, 8, 9, 15, 16, 17, 31, 32, 33, 39, 40])
def test_live_histograms_equal_every_boxs_on_the_live_slots(count):
    boxes = _boxes(count)
    for seed in range(3):
        alive = _alive(100 * count + seed, count)
        _check(_live(IMAGE, boxes, alive, patch_shape=PATCH), IMAGE, boxes, alive)
    # eager (the switch's index a concrete value)
    _check(live_box_histograms(IMAGE, boxes, alive, PATCH), IMAGE, boxes, alive)


def test_padding_never_writes_a_slot():
    """A bucket's padding entries gather a copy of the last box: with the last slot dead
    its zeros stay, with it alive its own histograms; slot 0 (where a fill index 0 would
    write) dead stays zero."""
    boxes = _boxes(1)
    for count in (1, 5, 9, 20):
        for last in (False, True):
            alive = np.zeros(SLOTS, bool)
            alive[1 : 1 + count] = True
            alive[-1] = last
            _check(_live(IMAGE, boxes, alive, patch_shape=PATCH), IMAGE, boxes, alive)


def test_a_box_outside_the_image_stays_zero_when_alive():
    boxes = _boxes(2)
    alive = np.ones(SLOTS, bool)
    boxes[0] = (10.0, 10.0, 20.0, 20.0)  # inside the 64 x 48 image
    result = np.asarray(_live(IMAGE, boxes, alive, patch_shape=PATCH))
    assert not np.any(result[SLOTS // 2])  # (100, 100): outside
    np.testing.assert_allclose(np.sum(result[0], axis=-1), 1.0, rtol=1e-6)


def test_vmap_over_members_with_different_counts():
    """A batch whose members fall in different buckets (the largest one's runs for all):
    each member equals its own oracle; the image shared (unbatched) or one per member."""
    counts = (0, 3, 9, 17, 40)
    alive = np.stack([_alive(7 + c, c) for c in counts])
    boxes = np.stack([_boxes(c) for c in counts])
    images = np.stack([np.roll(IMAGE, 5 * i, axis=1) for i in range(len(counts))])
    live = functools.partial(live_box_histograms, patch_shape=PATCH)
    shared = jax.jit(jax.vmap(live, in_axes=(None, 0, 0)))(IMAGE, boxes, alive)
    own = jax.jit(jax.vmap(live))(images, boxes, alive)
    same_boxes = jax.jit(jax.vmap(live, in_axes=(None, None, 0)))(IMAGE, boxes[-1], alive)
    for i in range(len(counts)):
        _check(shared[i], IMAGE, boxes[i], alive[i])
        _check(own[i], images[i], boxes[i], alive[i])
        _check(same_boxes[i], IMAGE, boxes[-1], alive[i])
    # A batch of batches (a sweep's configurations over scenes, say).
    nested = jax.jit(jax.vmap(jax.vmap(live, in_axes=(None, 0, 0)), in_axes=(None, 0, 0)))(
        IMAGE, boxes.reshape(len(counts), 1, SLOTS, 4), alive.reshape(len(counts), 1, SLOTS)
    )
    for i in range(len(counts)):
        _check(nested[i, 0], IMAGE, boxes[i], alive[i])


def test_under_vmap_the_bucket_stays_a_conditional():
    """Under vmap one bucket runs for the whole batch (a ``cond`` on an unbatched index);
    a switch on a batched index would be a select running every bucket for every member."""
    live = functools.partial(live_box_histograms, patch_shape=PATCH)
    alive = np.stack([_alive(1, 3), _alive(2, 20)])
    boxes = np.stack([_boxes(1), _boxes(2)])
    for in_axes in ((None, 0, 0), (0, 0, 0), (None, None, 0), (0, None, None)):
        images = np.stack([IMAGE, IMAGE])
        args = (IMAGE if in_axes[0] is None else images, boxes[0] if in_axes[1] is None else boxes)
        args += (alive[0] if in_axes[2] is None else alive,)
        jaxpr = jax.make_jaxpr(jax.vmap(live, in_axes=in_axes))(*args)
        conds = [e for e in jaxpr.jaxpr.eqns if e.primitive.name == "cond"]
        assert len(conds) == 1
        assert len(conds[0].params["branches"]) == len(bucket_sizes(SLOTS))
        assert conds[0].invars[0].aval.shape == ()  # the bucket index: one for the batch


def test_alive_must_match_the_boxes():
    with pytest.raises(InputError, match="alive"):
        live_box_histograms(IMAGE, _boxes(0), np.ones(SLOTS - 1, bool), PATCH)


# --- the tracker -----------------------------------------------------------------------------


def _every_box(image, boxes, alive, patch_shape):
    """The step before compaction: every low-level slot's histograms."""
    del alive
    return box_histograms(image, boxes, patch_shape)


def _infos(inputs, batched: bool):
    """Per-frame infos of the full tracker with 24 low-level slots (buckets 8, 16, 24),
    the stock and a second parameter set vmapped when ``batched``."""
    config = HierarchicalConfig(variant="full", max_tracks=24, max_trackers=8)
    filt, params = build_hierarchical(config, INFO, BACKGROUND)
    key = jax.random.PRNGKey(0)
    if not batched:
        _, info = jax.jit(lambda p, i: run(filt, key, p, i))(params, inputs)
        return jax.device_get(info)
    other = params._replace(max_lost=params.max_lost / 2, min_score=jnp.float32(0.5))
    stacked = jax.tree.map(lambda a, b: jnp.stack([a, b]), params, other)
    _, info = jax.jit(jax.vmap(lambda p, i: run(filt, key, p, i), in_axes=(0, None)))(
        stacked, inputs
    )
    return jax.device_get(info)


@pytest.mark.parametrize("batched", [False, True])
def test_the_tracker_outputs_equal_those_with_every_boxs_histograms(monkeypatch, batched):
    """Dead slots' histograms are read only under masks that discard them: the per-frame
    outputs (tracks, candidates, events, pools, distances, merges) are bit-identical."""
    inputs = occlusion_scene(num_slots=4)
    live = _infos(inputs, batched)
    monkeypatch.setattr(hierarchical, "live_box_histograms", _every_box)
    every = _infos(inputs, batched)
    for a, b in zip(jax.tree.leaves(live), jax.tree.leaves(every), strict=True):
        np.testing.assert_array_equal(a, b)
    assert (live.merged >= 0).sum() >= 1  # the scene's re-association happened
    assert np.any(live.pool >= 0)  # appearance was learned
