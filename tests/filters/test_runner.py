"""The sequence runner: jit == eager, vmap == loop, one compile, finite gradients."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.filters.base import run
from jaxtrack.filters.phd import phd_filter
from jaxtrack.filters.phd_defaults import default_phd_params
from tests.filters.phd_scenes import walking_scene

PARAMS = default_phd_params(640.0, 480.0, 25.0)
DETECTIONS, TRUTH = walking_scene(
    12,
    starts=[(100.0, 100.0), (400.0, 200.0)],
    velocities=[(4.0, 1.0), (-3.0, 0.5)],
    missed={3: {0}, 4: {0, 1}, 5: {0, 1}, 8: {1}},
    capacity=4,
)


def _close(a, b, **tolerance):
    jax.tree.map(lambda x, y: np.testing.assert_allclose(x, y, **tolerance), a, b)


@pytest.mark.slow
def test_jit_equals_eager():
    filt = phd_filter(64, births_per_detection=8, extraction="partition", max_tracks=8)
    key = jax.random.key(3)
    frames = jax.tree.map(lambda x: jnp.asarray(x[:2]), DETECTIONS)
    _, jitted = jax.jit(lambda k, p, d: run(filt, k, p, d))(key, PARAMS, frames)
    with jax.disable_jit():
        _, eager = run(filt, key, PARAMS, frames)
    _close(jitted, eager, rtol=1e-4, atol=1e-4)
    assert np.sum(jitted.tracks.mask) > 0


def test_vmap_over_params_equals_loop_and_gives_labelled_tracks():
    filt = phd_filter(64, births_per_detection=8, extraction="partition")
    batch = [
        PARAMS._replace(detection_prob=jnp.asarray(p), survival_prob=jnp.asarray(s))
        for p, s in [(0.9, 0.99), (0.7, 0.95), (0.95, 0.9)]
    ]
    stacked = jax.tree.map(lambda *x: jnp.stack(x), *batch)
    key = jax.random.key(0)
    single = jax.jit(lambda p: run(filt, key, p, DETECTIONS)[1])
    _, vmapped = jax.jit(jax.vmap(lambda p: run(filt, key, p, DETECTIONS)))(stacked)
    for i, params in enumerate(batch):
        _close(jax.tree.map(lambda x, i=i: x[i], vmapped), single(params), rtol=1e-4, atol=1e-4)
    assert vmapped.tracks.ids.shape == (3, 12, 4)
    # Both targets are labelled with two distinct persistent identities in every setting.
    for i in range(3):
        ids = np.asarray(vmapped.tracks.ids[i][vmapped.tracks.mask[i]])
        assert len(set(ids.tolist())) == 2


def test_vmap_over_keys():
    filt = phd_filter(64, births_per_detection=8)
    keys = jax.random.split(jax.random.key(1), 4)
    params = PARAMS._replace(detection_prob=jnp.asarray(0.9), survival_prob=jnp.asarray(0.99))
    _, info = jax.jit(jax.vmap(lambda k: run(filt, k, params, DETECTIONS)))(keys)
    assert info.mass.shape == (4, 12)
    assert not np.allclose(info.mass[0], info.mass[1])
    # Two detected targets, each near the fixed point 1 / (1 - (1 - pD) e) of the mass.
    np.testing.assert_allclose(info.mass[:, -1], 2 / (1 - 0.1 * 0.99), rtol=0.05)


def test_step_compiles_once_for_any_number_of_detections():
    filt = phd_filter(64, births_per_detection=8)
    step = jax.jit(filt.step)
    state = filt.init(jax.random.key(0), PARAMS)
    counts = set()
    for t in range(DETECTIONS.mask.shape[0]):
        frame = jax.tree.map(lambda x, t=t: jnp.asarray(x[t]), DETECTIONS)
        counts.add(int(frame.mask.sum()))
        state, _ = step(jax.random.key(t), state, PARAMS, frame)
    assert counts == {0, 1, 2}
    assert step._cache_size() == 1


@pytest.mark.parametrize("stop_gradient_resampling", [False, True])
def test_gradient_of_the_log_likelihood_is_finite_with_padded_and_empty_frames(
    stop_gradient_resampling,
):
    filt = phd_filter(64, births_per_detection=8, stop_gradient_resampling=stop_gradient_resampling)
    params = PARAMS._replace(score_weight=jnp.asarray(0.5))

    def total_log_likelihood(params):
        return jnp.sum(run(filt, jax.random.key(0), params, DETECTIONS)[1].log_likelihood)

    value, grads = jax.jit(jax.value_and_grad(total_log_likelihood))(params)
    assert np.isfinite(value)
    leaves = jax.tree.leaves(grads)
    assert all(np.all(np.isfinite(leaf)) for leaf in leaves if leaf.dtype.kind == "f")
    for name in ("detection_prob", "survival_prob", "score_weight"):
        assert abs(float(getattr(grads, name))) > 0, name
    assert np.all(np.asarray(grads.measurement_noise_std) != 0)
    assert float(grads.clutter_intensity.magnitude) != 0
    assert float(grads.birth_intensity.magnitude) != 0


def test_one_step_gradient_matches_finite_differences():
    """The first frames' log-likelihood is smooth in the parameters for fixed draws."""
    with jax.enable_x64(True):
        filt = phd_filter(64, births_per_detection=8)
        params = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype.kind == "f" else x, PARAMS
        )
        frames = jax.tree.map(
            lambda x: jnp.asarray(x[:2], jnp.float64 if x.dtype.kind == "f" else x.dtype),
            DETECTIONS,
        )

        def log_likelihood(values):
            """Frame 2's log-likelihood as a function of four scalar parameters."""
            detection_prob, score_weight, clutter_rate, noise_x = values
            changed = params._replace(
                detection_prob=detection_prob,
                score_weight=score_weight,
                clutter_intensity=params.clutter_intensity._replace(magnitude=clutter_rate),
                measurement_noise_std=params.measurement_noise_std.at[0].set(noise_x),
            )
            return run(filt, jax.random.key(0), changed, frames)[1].log_likelihood[1]

        values = jnp.array([0.9, 0.5, 1.0, 0.15])
        grad = jax.jit(jax.grad(log_likelihood))(values)
        value_at = jax.jit(jax.vmap(log_likelihood))
        steps = 1e-6 * jnp.eye(4)
        numeric = (value_at(values + steps) - value_at(values - steps)) / 2e-6
    assert np.all(np.asarray(grad) != 0)
    np.testing.assert_allclose(grad, numeric, rtol=1e-4)


def _compiled_functions(function):
    """Runs ``function()`` and lists the names of the functions XLA compiled meanwhile."""
    events = []

    def listener(event, duration, **kwargs):
        if event == "/jax/core/compile/backend_compile_duration":
            events.append(kwargs.get("fun_name"))

    jax.monitoring.register_event_duration_secs_listener(listener)
    try:
        result = function()
    finally:
        jax.monitoring.unregister_event_duration_listener(listener)
    return result, events


def test_chunked_run_equals_run_and_compiles_once():
    filt = phd_filter(256, births_per_detection=8)
    key = jax.random.PRNGKey(2)
    _, expected = jax.jit(lambda k, p, d: run(filt, k, p, d))(key, PARAMS, DETECTIONS)
    (_, chunked), compiled = _compiled_functions(
        lambda: run(filt, key, PARAMS, DETECTIONS, chunk_frames=5)  # 12 = 5 + 5 + 2
    )
    _close(chunked, expected, rtol=1e-5, atol=1e-5)
    assert compiled.count("jit(scan)") == 1
    shorter = jax.tree.map(lambda x: x[:7], DETECTIONS)
    (_, prefix), compiled = _compiled_functions(
        lambda: run(filt, key, PARAMS, shorter, chunk_frames=5)
    )
    _close(prefix, jax.tree.map(lambda x: x[:7], expected), rtol=1e-5, atol=1e-5)
    assert "jit(scan)" not in compiled  # the chunk scan compiled for 12 frames serves 7
    with pytest.raises(ValueError, match="chunk_frames must be positive"):
        run(filt, key, PARAMS, DETECTIONS, chunk_frames=0)


def test_checkpoint_and_frame_output_keep_the_per_frame_results():
    """``checkpoint`` changes memory, not values; ``frame_output`` sees each frame's state and
    index, chunked or not; gradients through the checkpointed run equal the plain ones."""
    filt = phd_filter(128, births_per_detection=4)
    key = jax.random.key(5)

    def output(state, info, index):
        return {"mass": state.mass, "log_likelihood": info.log_likelihood, "index": index}

    _, plain = jax.jit(lambda k: run(filt, k, PARAMS, DETECTIONS))(key)
    _, checked = jax.jit(
        lambda k: run(filt, k, PARAMS, DETECTIONS, checkpoint=True, frame_output=output)
    )(key)
    _, chunked = run(filt, key, PARAMS, DETECTIONS, chunk_frames=5, frame_output=output)
    for outputs in (checked, chunked):
        np.testing.assert_allclose(outputs["mass"], plain.mass, rtol=1e-5)
        np.testing.assert_allclose(outputs["log_likelihood"], plain.log_likelihood, rtol=1e-5)
        np.testing.assert_array_equal(outputs["index"], np.arange(12))

    def total(detection_prob, checkpoint):
        params = PARAMS._replace(detection_prob=detection_prob)
        _, out = run(filt, key, params, DETECTIONS, checkpoint=checkpoint, frame_output=output)
        return jnp.sum(out["log_likelihood"])

    grads = [
        jax.jit(jax.grad(total), static_argnums=1)(jnp.asarray(0.9), checkpoint)
        for checkpoint in (False, True)
    ]
    assert np.isfinite(grads[0]) and grads[0] != 0
    np.testing.assert_allclose(grads[1], grads[0], rtol=1e-5)
