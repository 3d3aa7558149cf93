"""COM's chance-level correction of the mutual information (not in the paper).

Oracles: a NumPy loop of the formula, Monte Carlo runs of the plug-in estimate on
independent samples (its mean is the chance level), and drawn look-alike and separable targets
whose decayed histograms are built as the tracker builds them.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.appearance import (
    chance_information,
    decay_update,
    feature_weights,
    field_of_context,
    multiresolution_mutual_information,
    mutual_information,
    quantise_values,
)
from jaxtrack.filters.cmt_observation import (
    default_com_params,
    drop_weak_features,
    observation_weights,
)
from jaxtrack.filters.cmt_tracker import CMTConfig, cmt_params

_chance = jax.jit(chance_information)
_plug_in = jax.jit(mutual_information)
_multiresolution = jax.jit(multiresolution_mutual_information, static_argnums=2)
_weights = jax.jit(feature_weights, static_argnums=2)


def _chance_loop(counts, classes):
    """(perplexity of the pooled values - 1)(classes with samples - 1) / (2 x mass)."""
    kept = [u for u in range(counts.shape[0]) if classes[u] and counts[u].sum() > 0]
    total = sum(counts[u].sum() for u in kept)
    if total == 0:
        return 0.0
    pooled = sum(counts[u] for u in kept) / total
    entropy = -sum(p * math.log(p) for p in pooled if p > 0)
    return max(0.0, (math.exp(entropy) - 1) * (len(kept) - 1) / (2 * total))


def test_chance_information_matches_loop():
    rng = np.random.default_rng(11)
    for _ in range(6):
        counts = rng.uniform(0, 3, (5, 8)) * (rng.uniform(0, 1, (5, 8)) < 0.5)
        classes = rng.uniform(0, 1, 5) < 0.7
        got = float(_chance(jnp.asarray(counts), jnp.asarray(classes)))
        assert got == pytest.approx(_chance_loop(counts, classes), rel=1e-4, abs=1e-7)
    both = jnp.array([True, True])
    assert float(_chance(jnp.zeros((2, 4)), both)) == 0.0  # no samples
    one = jnp.array([[1.0, 2.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]])
    assert float(_chance(one, both)) == 0.0  # one class holds samples: no identity to learn


def test_chance_information_is_the_plug_in_mean_under_independence():
    """Feature and identity independent: the plug-in ``I`` averages the chance level (within
    Monte Carlo and second-order error), and the corrected estimate averages about 0."""
    rng = np.random.default_rng(5)
    classes, per_class, bins = 3, 200, 6
    probs = np.array([0.3, 0.25, 0.2, 0.1, 0.1, 0.05])
    plug_in, chance = [], []
    for _ in range(400):
        counts = np.stack([rng.multinomial(per_class, probs) for _ in range(classes)])
        counts = jnp.asarray(counts, jnp.float32)
        plug_in.append(float(_plug_in(counts, jnp.ones(classes, bool))))
        chance.append(float(_chance(counts, jnp.ones(classes, bool))))
    expected = (bins - 1) * (classes - 1) / (2 * classes * per_class)  # Miller-Madow
    assert np.mean(plug_in) == pytest.approx(expected, rel=0.1)
    # The perplexity counts the bins in use as fewer than 6 (the distribution is skewed):
    # the chance level is a little below the plug-in mean, never above it here.
    assert 0.7 * np.mean(plug_in) < np.mean(chance) <= np.mean(plug_in)
    corrected = np.maximum(np.array(plug_in) - np.array(chance), 0.0)
    assert np.mean(corrected) < 0.35 * np.mean(plug_in)


def test_correction_zero_is_the_plug_in_estimate():
    rng = np.random.default_rng(2)
    counts = jnp.asarray(rng.uniform(0, 3, (4, 8)) * (rng.uniform(0, 1, (4, 8)) < 0.6))
    classes = jnp.array([True, True, False, True])
    plain = float(_multiresolution(counts, classes, 3))
    assert float(multiresolution_mutual_information(counts, classes, 3, 0.0)) == plain
    lowered = float(multiresolution_mutual_information(counts, classes, 3, 1.0))
    assert 0.0 <= lowered < plain


def _decayed_histograms(rng, spreads, shift, frames=60, num_values=16):
    """Two targets' decayed histograms (CMT eq. 16, decay 0.05) of features around 0.4 with
    per-feature spreads; target 1's feature 0 is ``shift`` higher."""
    counts = jnp.zeros((2, spreads.size, num_values))
    for _ in range(frames):
        values = 0.4 + spreads[None, :] * rng.standard_normal((2, spreads.size))
        values[1, 0] += shift
        bins = quantise_values(jnp.asarray(np.clip(values, 0.0, 1.0)), num_values)
        counts = decay_update(counts, bins, jnp.ones(2, bool), 0.05)
    return counts


def _mean_weights(shift, correction, trials=60):
    rng = np.random.default_rng(17)
    spreads = np.array([0.01, 0.03, 0.06, 0.12])
    weights = [
        np.asarray(
            _weights(
                _decayed_histograms(rng, spreads, shift), jnp.ones((2, 2), bool), 3, correction
            )[0]
        )
        for _ in range(trials)
    ]
    return np.mean(weights, axis=0)


def test_look_alike_targets_do_not_favour_the_noisiest_feature():
    """Two targets drawn from one distribution: no feature tells them apart. The plug-in
    weights go mostly to the feature that fluctuates most (its chance ``I`` is the largest);
    corrected, they spread over the features (not exactly uniform: the perplexity is a rough
    count of the bins in use, and what is left above chance is noise)."""
    plug_in = _mean_weights(0.0, 0.0)
    corrected = _mean_weights(0.0, 1.0)
    assert plug_in[3] > 0.45 and plug_in[0] < 0.06
    assert corrected[3] < 0.5 * plug_in[3]
    assert corrected.min() > 0.1

    def entropy(weights):
        return -float(np.sum(weights * np.log(weights)))

    assert entropy(corrected) > entropy(plug_in) + 0.15


def test_a_separating_feature_keeps_its_weight():
    """Target 1's feature 0 sits 0.3 higher (about 5 value bins): both estimates give it most
    of the weight; the corrected one gives it more (less goes to noise)."""
    plug_in = _mean_weights(0.3, 0.0)
    corrected = _mean_weights(0.3, 1.0)
    assert plug_in[0] > 0.8
    assert corrected[0] > plug_in[0]


def test_config_sets_the_correction():
    assert float(cmt_params(CMTConfig()).observation.information_correction) == 0.0
    params = cmt_params(CMTConfig(information_correction=1.0))
    assert float(params.observation.information_correction) == 1.0


def test_observation_weights_read_the_correction_also_in_a_sweep():
    """COM's weights with the correction on equal the corrected feature weights (then the
    weak features dropped); a vmapped sweep over ``[0, 1]`` gives both settings' weights."""
    rng = np.random.default_rng(23)
    counts = jnp.asarray(rng.uniform(0, 2, (4, 5, 16)) * (rng.uniform(0, 1, (4, 5, 16)) < 0.4))
    positions = jnp.asarray([[0.0, 0.0], [10.0, 0.0], [200.0, 0.0], [205.0, 5.0]])
    alive = jnp.array([True, True, True, False])
    context = field_of_context(positions, alive, 50.0)
    base = default_com_params()

    def weights(params):
        return observation_weights(counts, positions, alive, 50.0, params, 3, True)

    for correction in (0.0, 1.0):
        params = base._replace(information_correction=jnp.float32(correction))
        expected = drop_weak_features(
            feature_weights(counts, context, 3, correction), base.min_feature_score
        )
        np.testing.assert_allclose(weights(params), expected, rtol=1e-6)
    swept = jax.vmap(lambda c: weights(base._replace(information_correction=c)))(
        jnp.array([0.0, 1.0], jnp.float32)
    )
    for index, correction in enumerate((0.0, 1.0)):
        single = weights(base._replace(information_correction=jnp.float32(correction)))
        np.testing.assert_allclose(swept[index], single, rtol=1e-6)
    assert not np.allclose(swept[0], swept[1])  # the correction changes something here
