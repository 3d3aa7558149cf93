"""One Threefry evaluation for several draws equals the separate ``jax.random`` calls."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters import default_phd_params, draws, phd_filter
from jaxtrack.filters import phd as phd_module
from tests.filters.phd_scenes import padded_detections

LOWER = np.array([-3.0, -2.0], np.float32)
UPPER = np.array([3.0, 2.5], np.float32)


def _requests(k1, k2, k3, lower, upper):
    return [
        draws.normal(k1, (2048, 4)),
        draws.normal(k2, (9, 32, 4)),
        draws.uniform(k3, (288, 2), lower, upper),
        draws.uniform(k1, ()),
        draws.normal(k3, (7,)),  # odd size
    ]


def _separate(k1, k2, k3, lower, upper):
    return [
        jax.random.normal(k1, (2048, 4)),
        jax.random.normal(k2, (9, 32, 4)),
        jax.random.uniform(k3, (288, 2), minval=lower, maxval=upper),
        jax.random.uniform(k1, ()),
        jax.random.normal(k3, (7,)),
    ]


@pytest.mark.parametrize("make_key", [jax.random.key, jax.random.PRNGKey], ids=["typed", "raw"])
def test_one_evaluation_equals_separate_draws_bit_for_bit(make_key):
    keys = jax.random.split(make_key(3), 3)
    merged = jax.jit(lambda *a: draws.draw(_requests(*a)))(*keys, LOWER, UPPER)
    separate = jax.jit(_separate)(*keys, LOWER, UPPER)
    for got, expected in zip(merged, separate, strict=True):
        assert got.shape == expected.shape and got.dtype == expected.dtype
        np.testing.assert_array_equal(got, expected)
    # The draws are what they claim: standard normals and uniforms in the range.
    assert abs(float(jnp.mean(merged[0]))) < 0.05 and abs(float(jnp.std(merged[0])) - 1) < 0.05
    assert np.all((merged[2] >= LOWER) & (merged[2] < UPPER))


def test_one_evaluation_under_vmap_equals_the_draws_key_by_key():
    # Batched keys (a sweep's configurations): equal to each key's own draws up to the
    # rounding of the uniform's scaling (XLA may contract its multiply-add in a batched fusion).
    keys = [jax.random.split(k, 4) for k in jax.random.split(jax.random.key(5), 3)]
    merged = jax.vmap(lambda *a: draws.draw(_requests(*a, LOWER, UPPER)))(*keys)
    for b in range(4):
        expected = jax.jit(_separate)(keys[0][b], keys[1][b], keys[2][b], LOWER, UPPER)
        for got, want in zip(merged, expected, strict=True):
            np.testing.assert_allclose(got[b], want, rtol=1e-6, atol=1e-6)


def test_other_keys_and_float64_are_drawn_separately():
    key = jax.random.key(1, impl="rbg")
    (got,) = draws.draw([draws.normal(key, (5, 3))])
    np.testing.assert_array_equal(got, jax.random.normal(key, (5, 3)))
    with jax.enable_x64(True):
        key = jax.random.key(2)
        got = draws.draw([draws.uniform(key, (6,), 1.0, 2.0, jnp.float64)])[0]
        assert got.dtype == jnp.float64
        np.testing.assert_array_equal(got, jax.random.uniform(key, (6,), jnp.float64, 1.0, 2.0))


def test_tracker_step_gives_the_same_frame_with_stages_drawing_for_themselves():
    # A predict stage the step does not recognise draws its own numbers from its key; the
    # step's one joint evaluation must give the same particles, weights and tracks.
    params = default_phd_params(768, 576, 7.0)
    filt = phd_filter(256, births_per_detection=8)
    detections = padded_detections([[(100.0, 120.0, 40.0, 90.0), (400.0, 300.0, 35.0, 80.0)]], 4)
    frame = jax.tree.map(lambda x: x[0], detections)
    key = jax.random.key(11)
    state = filt.init(key, params)
    state, _ = jax.jit(filt.step)(key, state, params, frame)  # particles on the targets

    def own_draws(*args, **kwargs):
        return phd_module.predict(*args, **kwargs)

    joint = jax.jit(filt.step)(jax.random.key(12), state, params, frame)
    step = functools.partial(phd_module.phd_step, **{**filt.step.keywords, "predict": own_draws})
    separate = jax.jit(step)(jax.random.key(12), state, params, frame)
    assert phd_module._joint_draws(own_draws, None, key, key, state, frame) == ({}, {})
    for got, expected in zip(jax.tree.leaves(joint), jax.tree.leaves(separate), strict=True):
        np.testing.assert_array_equal(got, expected)


def test_hash_equals_jax_threefry_on_every_word():
    """The written-out hash gives ``threefry2x32_p``'s two output words for per-element keys
    and counters, high counter words and the words' extreme values included (independent
    oracle: JAX's own primitive)."""
    from jax.extend.random import threefry2x32_p

    rng = np.random.default_rng(7)
    words = rng.integers(0, 2**32, (4, 1000), dtype=np.uint64).astype(np.uint32)
    words[:, :4] = [[0, 0xFFFFFFFF, 0, 0xFFFFFFFF]] * 4
    key_hi, key_lo, count_hi, count_lo = (jnp.asarray(w) for w in words)
    expected = threefry2x32_p.bind(key_hi, key_lo, count_hi, count_lo)
    got = jax.jit(draws.threefry2x32)(key_hi, key_lo, count_hi, count_lo)
    for want, have in zip(expected, got, strict=True):
        np.testing.assert_array_equal(np.asarray(have), np.asarray(want))


def test_recursion_draws_are_the_stages_own_draws():
    # The benchmark's recursion and the tracker's step share phd.recursion_draws: motion noise
    # as predict draws it from its key, births' numbers as draw_births splits and draws its key.
    key_motion, key_birth = jax.random.split(jax.random.key(21))
    normal, random = phd_module.recursion_draws(
        key_motion, key_birth, 96, jnp.float32, (5, 3, jnp.float32)
    )
    np.testing.assert_array_equal(normal, jax.random.normal(key_motion, (96, 4)))
    key_gauss, key_velocity = jax.random.split(key_birth)
    np.testing.assert_array_equal(random[0], jax.random.normal(key_gauss, (5, 3, 4)))
    np.testing.assert_array_equal(random[1], jax.random.uniform(key_velocity, (15, 2)))
    alone, none = phd_module.recursion_draws(key_motion, key_birth, 96, jnp.float32)
    np.testing.assert_array_equal(alone, normal)
    assert none is None


def _words(keys):
    if jax.dtypes.issubdtype(keys.dtype, jax.dtypes.prng_key):
        return np.asarray(jax.random.key_data(keys))
    return np.asarray(keys)


@pytest.mark.parametrize("make_key", [jax.random.key, jax.random.PRNGKey], ids=["typed", "raw"])
@pytest.mark.parametrize("num", [1, 2, 4, 795])
def test_split_equals_jax_random_split_bit_for_bit(make_key, num):
    for seed in (0, 17, 2**31 + 5):
        key = make_key(seed)
        expected = jax.random.split(key, num)
        got = jax.jit(draws.split, static_argnums=1)(key, num)
        assert got.dtype == expected.dtype and got.shape == expected.shape
        np.testing.assert_array_equal(_words(got), _words(expected))
    # Batched keys (run_batch splits every configuration's key).
    keys = jax.random.split(make_key(9), 3)
    batched = jax.vmap(lambda k: draws.split(k, num))(keys)
    for b in range(3):
        np.testing.assert_array_equal(_words(batched[b]), _words(jax.random.split(keys[b], num)))


def test_split_of_another_key_implementation_is_jax_random_split():
    key = jax.random.key(4, impl="rbg")
    np.testing.assert_array_equal(_words(draws.split(key, 3)), _words(jax.random.split(key, 3)))


def test_unwritten_draws_equal_the_written_ones():
    keys = jax.random.split(jax.random.key(6), 3)
    written = jax.jit(lambda *a: draws.draw(_requests(*a)))(*keys, LOWER, UPPER)
    fused = jax.jit(lambda *a: draws.draw(_requests(*a), written=False))(*keys, LOWER, UPPER)
    for got, expected in zip(fused, written, strict=True):
        np.testing.assert_array_equal(got, expected)
    # The resampling's single uniform is jax.random.uniform's number.
    key = jax.random.key(11)
    (offset,) = jax.jit(lambda k: draws.draw([draws.uniform(k, ())], written=False))(key)
    np.testing.assert_array_equal(offset, jax.random.uniform(key, ()))
