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


def std_columns(
    noise_model: NoiseModel, sizes: Float[Array, "... 2"], noise_std: Float[Array, " 4"]
) -> tuple[Array, ...]:
    """The four standard deviations of ``noise_model(sizes, noise_std)`` as four
    ``[..., 1]`` arrays (the output's columns, the trailing axis kept).

    The same values as the model's ``[..., 4]`` output, element for element. For the two
    models of this module they are formed directly (``noise_std[k] * w`` or ``* h``, and
    ``noise_std[k]`` broadcast), so a caller that uses the columns apart never writes the
    stacked array: XLA:CPU materialised the SDV stack of the dynamics' noise, a pass over
    memory of 16 bytes per particle. Another model's output is sliced. The trailing axis is
    kept because XLA:CPU's fused loops over ``[n, 6]`` states read ``[n, 1]`` columns
    faster than ``[n]`` vectors broadcast back (twice as fast in the dynamics' fusion at a
    million particles).
    """
    if noise_model is state_dependent_std:
        width, height = sizes[..., 0:1], sizes[..., 1:2]
        return tuple(noise_std[k] * size for k, size in enumerate((width, height, width, height)))
    if noise_model is constant_std:
        column = (*sizes.shape[:-1], 1)
        return tuple(jnp.broadcast_to(noise_std[k], column) for k in range(4))
    std = noise_model(sizes, noise_std)
    return tuple(std[..., k : k + 1] for k in range(4))
