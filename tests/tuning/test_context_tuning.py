"""Tuning a learned context: the uniform shares as named leaves, the defaults per variant, the
tuned context read back by ``phd_params``, clear refusals, and gradients in the shares.

The context is a small synthetic scene's true one (``context_truth``) with a uniform share of
0.3 given to its birth density (the truth has none), so that both densities have live
Gaussians and ``pi_u`` in ``(0, 1)``, as a learned context has.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.learn import volume_mass
from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene, write_scene
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import (
    UNIFORM_SHARES,
    VARIANTS,
    Context,
    PHDConfig,
    context_names,
    phd_params,
    tuned_context,
)
from jaxtrack.filters.registry import properties_of
from jaxtrack.io import load_sequence
from jaxtrack.parameters import SHARE, named_leaves
from jaxtrack.pipelines.tuning import context_trainable, tune_sequence
from jaxtrack.tuning import likelihood_objective, parameter_space, tuning_filter

SCENE = generate_scene(
    5, SceneConfig(num_frames=10, burn_in_frames=60, birth_rate=0.2, uniform_clutter_rate=1.0)
)
BIRTH_SHARE = 0.3
CONTEXT = Context(
    SCENE.birth_intensity._replace(uniform_weight=jnp.asarray(BIRTH_SHARE, jnp.float32)),
    SCENE.clutter_intensity,
    {},
)
CONFIG = PHDConfig(birth_rate=0.5, clutter_rate=3.0)
SHARES = tuple(UNIFORM_SHARES.values())


def _with_recorded_masses(context: Context) -> Context:
    """The context with learn-context's metadata: events per frame and volume masses."""
    metadata = {}
    for part in ("birth", "clutter"):
        intensity = getattr(context, part)
        mass = volume_mass(intensity, jax.random.key(3))
        metadata[part] = {"magnitude": float(intensity.magnitude) * mass, "volume_mass": mass}
    return context._replace(metadata=metadata)


def test_uniform_shares_are_named_frozen_share_leaves_with_a_round_trip():
    params = phd_params(CONFIG, SCENE.info, CONTEXT, "GM")
    named = named_leaves(properties_of(params))
    for name in SHARES:
        assert named[name].transform is SHARE and not named[name].trainable
    space = parameter_space(params, SHARES)
    assert space.trainable == ("birth_uniform_share", "clutter_uniform_share")
    theta = space.to_unconstrained(params)
    clutter_share = float(SCENE.clutter_intensity.uniform_weight)
    expected = {"birth_uniform_share": BIRTH_SHARE, "clutter_uniform_share": clutter_share}
    for name, share in expected.items():
        np.testing.assert_allclose(theta[name], np.log(share / (1 - share)), rtol=1e-5)
    back = space.to_params(theta, params)
    jax.tree.map(lambda a, b: np.testing.assert_allclose(a, b, rtol=1e-5), back, params)
    moved = space.to_params({**theta, "birth_uniform_share": jnp.asarray(0.0)}, params)
    assert float(moved.birth_intensity.uniform_weight) == pytest.approx(0.5)
    assert float(moved.clutter_intensity.uniform_weight) == pytest.approx(clutter_share)
    np.testing.assert_array_equal(moved.birth_intensity.weights, params.birth_intensity.weights)


def test_a_uniform_intensity_has_no_share_to_tune():
    uniform = phd_params(CONFIG, SCENE.info)
    space = parameter_space(uniform, ["clutter_uniform_share"])
    with pytest.raises(InputError, match=r"clutter_uniform_share must be in \[0, 1\)"):
        space.to_unconstrained(uniform)
    # A pure mixture (pi_u = 0, e.g. a true context) is tunable: the logit clips it.
    truth = phd_params(CONFIG, SCENE.info, CONTEXT._replace(birth=SCENE.birth_intensity))
    theta = parameter_space(truth, ["birth_uniform_share"]).to_unconstrained(truth)
    assert np.isfinite(theta["birth_uniform_share"]) and theta["birth_uniform_share"] < -13


def test_default_trainable_parameters_follow_the_variant():
    def defaults(context, variant):
        return set(context_trainable(phd_params(CONFIG, SCENE.info, context, variant), variant))

    everything = {"birth_rate", "clutter_rate", *SHARES}
    assert defaults(CONTEXT, "GM") == defaults(CONTEXT, "A6") == everything
    assert defaults(CONTEXT, "A1") == {"birth_rate", "birth_uniform_share"}
    assert defaults(CONTEXT, "A2") == {"clutter_rate", "clutter_uniform_share"}
    assert defaults(CONTEXT, "A3") == {"birth_rate", "clutter_rate"}
    assert defaults(CONTEXT, "A4") == {"birth_rate", "clutter_rate", "birth_uniform_share"}
    # A density the learner left uniform (pi_u = 1) has no share to tune.
    uniform_clutter = CONTEXT.clutter._replace(uniform_weight=jnp.asarray(1.0))
    fallen_back = CONTEXT._replace(clutter=uniform_clutter)
    assert defaults(fallen_back, "GM") == {"birth_rate", "clutter_rate", "birth_uniform_share"}


@pytest.mark.parametrize("recorded", [False, True])
@pytest.mark.parametrize("variant", sorted(set(VARIANTS) - {"UM"}))
def test_phd_params_of_the_tuned_context_are_the_tuned_params(variant, recorded):
    """Every variant: the tuned context gives back the tuned intensities, and its metadata
    the events per frame ``lambda = m P_p(V)`` of the tuned density (or ``m`` for a uniform
    density with a measured magnitude)."""
    context = _with_recorded_masses(CONTEXT) if recorded else CONTEXT
    params = phd_params(CONFIG, SCENE.info, context, variant)
    taken = context_names(variant)
    tuned_values = {"birth_rate": 0.07, "clutter_rate": 2.5}
    tuned_values.update({"birth_uniform_share": 0.12, "clutter_uniform_share": 0.45})
    names = tuple(name for name in tuned_values if name in taken)
    space = parameter_space(params, names)
    theta = {
        name: (jnp.log if name.endswith("_rate") else SHARE.inverse)(
            jnp.asarray(tuned_values[name])
        )
        for name in names
    }
    tuned = space.to_params(theta, params)
    record = {"frames": [1, 10], "objective": "likelihood"}
    context_out = tuned_context(context, tuned, variant, record)
    again = phd_params(CONFIG, SCENE.info, context_out, variant)
    for part in ("birth", "clutter"):
        got, want = (getattr(p, f"{part}_intensity") for p in (again, tuned))
        np.testing.assert_allclose(got.magnitude, want.magnitude, rtol=1e-5)
        np.testing.assert_allclose(got.uniform_weight, want.uniform_weight, rtol=1e-6)
        if f"{part}_rate" not in taken:
            assert getattr(context_out, part) == getattr(context, part)
            continue
        rate = context_out.metadata[part]["magnitude"]
        learned = getattr(VARIANTS[variant], f"learned_{part}")
        if learned:
            # P_p(V) of the tuned share: recorded P_GMM(V) or Monte Carlo, 1e-2 apart at most.
            fresh = volume_mass(getattr(context_out, part), jax.random.key(11))
            assert context_out.metadata[part]["volume_mass"] == pytest.approx(fresh, abs=1e-2)
            expected = tuned_values[f"{part}_rate"] * context_out.metadata[part]["volume_mass"]
            assert rate == pytest.approx(expected, rel=1e-5)
        else:
            assert rate == pytest.approx(tuned_values[f"{part}_rate"], rel=1e-5)
    assert context_out.metadata["tuning"] == [record]


@pytest.fixture(scope="module")
def sequence(tmp_path_factory):
    scene = generate_scene(1, dataclasses.replace(SceneConfig(), num_frames=12))
    return load_sequence(write_scene(scene, tmp_path_factory.mktemp("ctx-tune") / "SYN-1"))


def test_uniform_shares_without_a_learned_density_are_refused(sequence):
    with pytest.raises(InputError, match="needs a learned context"):
        tune_sequence(sequence, trainable=["birth_rate", "birth_uniform_share"])
    with pytest.raises(InputError, match="variant A2 uses no learned birth density"):
        tune_sequence(sequence, trainable=["birth_uniform_share"], context=CONTEXT, variant="A2")
    uniform_clutter = CONTEXT.clutter._replace(uniform_weight=jnp.asarray(1.0))
    with pytest.raises(InputError, match="clutter density is uniform"):
        tune_sequence(
            sequence,
            trainable=["clutter_uniform_share"],
            context=CONTEXT._replace(clutter=uniform_clutter),
        )
    with pytest.raises(InputError, match="variant UM uses no context"):
        tune_sequence(sequence, context=CONTEXT, variant="UM")


def test_initial_rate_is_refused_where_the_context_starts_the_run(sequence):
    with_initial = CONTEXT._replace(initial=CONTEXT.birth._replace(magnitude=jnp.asarray(4.0)))
    for variant in ("GM", "A1", "A4", "A6"):
        with pytest.raises(InputError, match=f"initial_rate: variant {variant} starts from"):
            tune_sequence(
                sequence, trainable=["initial_rate"], context=with_initial, variant=variant
            )
    # allowed where it is read: births uniform, or a context without a first-frame intensity
    allowed = dict(
        trainable=["initial_rate"], num_steps=1, num_keys=1, num_particles=64, average_steps=1
    )
    assert tune_sequence(sequence, context=with_initial, variant="A3", **allowed).context
    assert tune_sequence(sequence, context=CONTEXT, variant="GM", **allowed).context


def test_gradients_in_the_context_leaves_match_finite_differences():
    """Gradient of the likelihood objective in the magnitudes and the uniform shares against
    central differences (float64, step 1e-6, naive estimator, common random numbers; the
    tolerances of tests/tuning/test_gradients.py); the shares' gradients are not zero."""
    names = ("birth_rate", "birth_uniform_share", "clutter_rate", "clutter_uniform_share")
    step = 1e-6
    with jax.enable_x64(True):
        params = phd_params(CONFIG, SCENE.info, CONTEXT, "GM")
        params = jax.tree.map(lambda x: jnp.asarray(x, jnp.float64), params)
        detections = jax.tree.map(
            lambda x: jnp.asarray(x, jnp.float64) if x.dtype.kind == "f" else jnp.asarray(x),
            SCENE.detections,
        )
        space = parameter_space(params, names)
        objective = likelihood_objective(
            tuning_filter(64, births_per_detection=8, estimator="none")
        )
        theta = {k: jnp.asarray(v, jnp.float64) for k, v in space.to_unconstrained(params).items()}
        center = jnp.stack([theta[name] for name in space.trainable])

        def value(vector):
            point = dict(zip(space.trainable, vector, strict=True))
            return objective.loss(space.to_params(point, params), jax.random.key(7), detections)[0]

        shifts = step * jnp.eye(center.size)
        points = jnp.concatenate([center[None], center + shifts, center - shifts])
        values, grads = jax.jit(jax.vmap(jax.value_and_grad(value)))(points)
        n = center.size
        differences = np.asarray((values[1 : n + 1] - values[n + 1 :]) / (2 * step))
        gradient = np.asarray(grads[0])
    assert np.all(np.isfinite(gradient)) and np.isfinite(float(values[0]))
    scale = np.abs(gradient).max()
    np.testing.assert_allclose(gradient, differences, rtol=1e-4, atol=1e-6 * scale)
    for name in SHARES:
        assert abs(gradient[space.trainable.index(name)]) > 1e-3 * scale, name
