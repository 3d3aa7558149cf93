"""TEMPORARY STAND-IN (not committed): the helper's module replaces it."""
from typing import NamedTuple
import jax, jax.numpy as jnp
from jaxtrack.appearance import top_bottom_histograms, marginals
from jaxtrack.appearance.mutual_information import feature_values, decay_update, quantise_values
class COMParams(NamedTuple):
    feature_std: jax.Array; decay: jax.Array; min_feature_score: jax.Array; model_rate: jax.Array
def default_com_params():
    return COMParams(jnp.float32(0.1), jnp.float32(0.1), jnp.float32(0.5), jnp.float32(0.1))
class AppearanceState(NamedTuple):
    model: jax.Array; counts: jax.Array; initialised: jax.Array
def init_appearance(k, f, v):
    return AppearanceState(jnp.zeros((k, f)), jnp.zeros((k, f, v)), jnp.zeros(k, bool))
def box_features(frame, box, step, patch_shape):
    h = top_bottom_histograms(frame, box, patch_shape, step)
    m = marginals(h, 3, 8) if False else jnp.zeros((2, 3, 8))
    return feature_values(m, box)
def observation_weights(counts, positions, alive, radius, params, num_levels, contextual):
    return jnp.full(counts.shape[:2], 1.0 / counts.shape[1])
def appearance_log_likelihood(features, state, rho, params):
    d = features - state.model[:, None]
    l = jax.nn.logsumexp(jnp.log(rho)[:, None] - 0.5 * (d / params.feature_std) ** 2, axis=-1)
    return jnp.where(state.initialised[:, None], l, 0.0)
def update_appearance(state, features, observed, frozen, born, params, num_values):
    upd = observed & ~frozen
    model = jnp.where(born[:, None], features, jnp.where(upd[:, None], (1 - params.model_rate) * state.model + params.model_rate * features, state.model))
    counts = jnp.where(born[:, None, None], 0.0, state.counts)
    counts = decay_update(counts, quantise_values(features, num_values), upd | born, params.decay)
    return AppearanceState(model, counts, state.initialised | born)
