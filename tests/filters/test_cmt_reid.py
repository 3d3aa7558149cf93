"""CMT's re-identification of deleted components (``CMTConfig.reidentify_seconds``).

Oracles: the Bhattacharyya distance against a NumPy loop, hand-built graveyards whose gates
are known, and a drawn scene (tests/filters/test_cmt.py's two-tone targets) in which a target
is hidden for longer than its component lives.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.cmt import Graveyard, colour_distance, reidentified
from jaxtrack.filters.cmt_observation import init_appearance, num_features
from jaxtrack.filters.cmt_tracker import CMTConfig, build_cmt, reidentify_frames
from jaxtrack.types import SequenceInfo
from tests.filters.test_cmt import COLOURS, INFO, SMALL, scene

BINS = 8  # ceil(256 / 32), the default quantisation step
FEATURES = num_features()


def random_features(rng, rows):
    """Feature vectors: six normalised histograms of 8 buckets, then a shape value."""
    hist = rng.gamma(0.5, size=(rows, 6, BINS))
    hist /= hist.sum(axis=-1, keepdims=True)
    return np.concatenate([hist.reshape(rows, -1), rng.uniform(0.2, 0.4, (rows, 1))], axis=1)


def test_colour_distance_matches_a_numpy_loop():
    rng = np.random.default_rng(0)
    a, b = random_features(rng, 3), random_features(rng, 4)
    got = np.asarray(colour_distance(jnp.asarray(a, jnp.float32), jnp.asarray(b, jnp.float32)))
    for i in range(3):
        for j in range(4):
            coefficient = np.mean(
                [
                    np.sum(
                        np.sqrt(a[i, k * BINS : (k + 1) * BINS] * b[j, k * BINS : (k + 1) * BINS])
                    )
                    for k in range(6)
                ]
            )
            assert got[i, j] == pytest.approx(np.sqrt(max(1 - coefficient, 0)), abs=1e-3)
    assert np.asarray(colour_distance(jnp.asarray(a[:1]), jnp.asarray(a[:1])))[0, 0] < 1e-3


def graveyard(features, estimates, frames, ids):
    appearance = init_appearance(len(ids), FEATURES)._replace(
        model=jnp.asarray(features, jnp.float32), initialised=jnp.ones(len(ids), bool)
    )
    return Graveyard(
        ids=jnp.asarray(ids, jnp.int32),
        estimates=jnp.asarray(estimates, jnp.float32),
        frames=jnp.asarray(frames, jnp.int32),
        appearance=appearance,
    )


def state(cx, cy, w=20.0, h=50.0, vx=0.0, vy=0.0):
    return [cx, vx, cy, vy, w, h]  # the state layout: position and velocity interleaved


def test_reidentified_applies_its_gates():
    rng = np.random.default_rng(1)
    colours = random_features(rng, 3)
    # Entry 0: id 7, deleted at frame 10 at (100, 100) moving +2 px/frame in x.
    dead = graveyard(colours[:2], [state(100, 100, vx=2.0), state(0, 0)], [10, 0], [7, -1])
    frame = jnp.int32(15)  # age 5: predicted centre (110, 100), gate 1.5 heights = 75 px

    def match(decision, features, born=True, frame=frame, reidentify=25):
        decisions = jnp.asarray([state(0, 0), decision], jnp.float32)
        feats = jnp.asarray(np.stack([colours[2], features]), jnp.float32)
        return np.asarray(
            reidentified(dead, jnp.array([False, born]), decisions, feats, frame, reidentify)
        ).tolist()

    assert match(state(110, 100), colours[0]) == [-1, 0]
    assert match(state(180, 100), colours[0]) == [-1, 0]  # 70 px: inside the gate
    assert match(state(190, 100), colours[0]) == [-1, -1]  # 80 px: outside
    assert match(state(110, 100, h=80.0), colours[0]) == [-1, -1]  # 1.6x taller
    assert match(state(110, 100), colours[2]) == [-1, -1]  # other colours
    assert match(state(110, 100), colours[0], born=False) == [-1, -1]  # not a newborn
    assert match(state(110, 100), colours[0], frame=jnp.int32(40)) == [-1, -1]  # age 30 > 25
    assert match(state(110, 100), colours[0], frame=jnp.int32(10)) == [-1, -1]  # same frame


def test_two_newborns_get_one_identity_the_nearer_in_colour():
    rng = np.random.default_rng(2)
    colours = random_features(rng, 1)
    near = colours[0] * 0.98 + 0.02 / BINS  # slightly off the model, still alike
    near[-1] = colours[0, -1]
    dead = graveyard(colours, [state(100, 100)], [10], [3])
    decisions = jnp.asarray([state(100, 100), state(105, 100)], jnp.float32)
    features = jnp.asarray(np.stack([near, colours[0]]), jnp.float32)
    got = reidentified(dead, jnp.array([True, True]), decisions, features, jnp.int32(12), 25)
    assert np.asarray(got).tolist() == [-1, 0]


def hidden_target(colours, num_frames=40, hidden=range(10, 25)):
    """One target walking right at 2 px/frame, not drawn nor detected on ``hidden``."""
    truth = [[] if t in hidden else [(20.0 + 2 * t, 40.0, 16.0, 36.0)] for t in range(num_frames)]
    return scene(truth, colours)


@pytest.mark.parametrize("variant", ["mtb", "cmt"])
def test_a_target_hidden_longer_than_its_component_lives_keeps_its_identity(variant):
    inputs = hidden_target(COLOURS[:1])
    ids = {}
    for seconds in (0.0, 1.0):
        config = CMTConfig(variant=variant, reidentify_seconds=seconds, **SMALL)
        filt, params = build_cmt(config, INFO)
        _, info = jax.jit(lambda k, p, i, f=filt: run(f, k, p, i))(
            jax.random.PRNGKey(0), params, inputs
        )
        mask, shown = np.asarray(info.tracks.mask), np.asarray(info.tracks.ids)
        ids[seconds] = sorted({int(i) for i in shown[mask]})
        assert mask[30:].sum(axis=1).tolist() == [1] * 10  # tracked again after it came back
    assert len(ids[0.0]) == 2  # the paper's tracker: a new identity after the gap
    assert ids[1.0] == [0]  # re-identified: the first identity throughout


def test_another_person_at_the_spot_gets_a_new_identity():
    # The target that comes back is dressed differently: no re-identification.
    frames_a = hidden_target(COLOURS[:1])
    frames_b = hidden_target(COLOURS[1:])
    frame_images = np.where(
        (np.arange(40) < 25)[:, None, None, None], frames_a.frame, frames_b.frame
    )
    inputs = frames_a._replace(frame=jnp.asarray(frame_images))
    config = CMTConfig(variant="cmt", reidentify_seconds=1.0, **SMALL)
    filt, params = build_cmt(config, INFO)
    _, info = run(filt, jax.random.PRNGKey(0), params, inputs)
    mask, shown = np.asarray(info.tracks.mask), np.asarray(info.tracks.ids)
    assert mask[30:].sum(axis=1).tolist() == [1] * 10
    assert len({int(i) for i in shown[mask]}) == 2


def test_seconds_become_frames():
    assert reidentify_frames(CMTConfig(reidentify_seconds=0.0), INFO) == 0
    assert reidentify_frames(CMTConfig(), INFO) == 25  # 1 s by default
    assert reidentify_frames(CMTConfig(reidentify_seconds=2.0), INFO) == 50
    seven = SequenceInfo("pets", 30, 768, 576, 7.0)
    assert reidentify_frames(CMTConfig(reidentify_seconds=2.0), seven) == 14
    no_rate = SequenceInfo("bare", 30, 768, 576, None)
    assert reidentify_frames(CMTConfig(reidentify_seconds=0.01), no_rate) == 1
