"""TEMPORARY STAND-IN (not committed): the helper's module replaces it."""
from typing import NamedTuple
import jax, jax.numpy as jnp
from jaxtrack.filters.mixture_models import bootstrap_proposal
NORMAL, SPLIT, MERGE, EXIT, ENTER = 0, 1, 2, 3, 4
class CPDParams(NamedTuple):
    context_distance: jax.Array
def default_cpd_params():
    return CPDParams(jnp.float32(1.5))
class CPDDraw(NamedTuple):
    particles: jax.Array; log_q: jax.Array; conditions: jax.Array; exited: jax.Array; probabilities: jax.Array
def contextual_proposal(key, particles, estimates, alive, params, motion_noise_std, blobs, zone_boxes, zone_mask):
    from jaxtrack.filters.mixture_state import MixtureParams
    p = MixtureParams(motion_noise_std, motion_noise_std, 0.0, 0.0, 0.0, 0.0)
    new, lq = bootstrap_proposal(key, particles, p, blobs)
    return CPDDraw(new, lq, jnp.zeros(lq.shape, jnp.int32), jnp.zeros(lq.shape, bool), jnp.zeros((particles.shape[0], 4)))
