"""Noise models: how the standard deviation of a Gaussian noise depends on the box.

PHD-context Sec. III uses state-dependent variances (SDV): bigger boxes move and change more
and are detected less precisely. A noise model maps a box size and a vector of noise
parameters to per-dimension standard deviations, so that the dynamics and the likelihood
share one code path for both the SDV and the constant-noise variants.

A noise model is a function ``(sizes[..., 2], noise_std[4]) -> std[..., 4]`` where
``sizes = (w, h)`` and the four output dimensions follow ``(dim 1, dim 2, w, h)``.
"""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
from jaxtyping import Array, Float

NoiseModel = Callable[[Float[Array, "... 2"], Float[Array, " 4"]], Float[Array, "... 4"]]


def state_dependent_std(
    sizes: Float[Array, "... 2"], noise_std: Float[Array, " 4"]
) -> Float[Array, "... 4"]:
    """SDV noise: ``noise_std * (w, h, w, h)`` (PHD-context Sec. III, ``B(x)`` and ``Sigma(x)``).

    Args:
        sizes: box widths and heights ``(w, h)``, positive.
        noise_std: relative standard deviations ``(s_1, s_2, s_w, s_h)``, positive: dimension 1
            and the width scale with the width, dimension 2 and the height with the height.

    Returns:
        The standard deviations, in pixels.
    """
    width, height = sizes[..., 0], sizes[..., 1]
    return noise_std * jnp.stack([width, height, width, height], axis=-1)


def constant_std(
    sizes: Float[Array, "... 2"], noise_std: Float[Array, " 4"]
) -> Float[Array, "... 4"]:
    """Constant noise: ``noise_std`` in pixels whatever the box size.

    Args:
        sizes: box widths and heights (only their batch shape is used).
        noise_std: standard deviations in pixels, positive.

    Returns:
        ``noise_std`` broadcast to ``sizes.shape[:-1] + (4,)``.
    """
    return jnp.broadcast_to(noise_std, (*sizes.shape[:-1], 4))
