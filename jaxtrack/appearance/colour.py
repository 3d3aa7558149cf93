"""Colour spaces and colour features of sampled pixels, on a common ``[0, 256]`` scale.

Each function maps RGB pixels (float, ``[0, 255]``, last axis ``R, G, B``) to ``C`` channel
values on the scale of 8-bit intensities, so that one quantisation step ``lambda``
(:func:`jaxtrack.appearance.histograms.quantise`, bins of width ``lambda``) serves every
space. Channels that are fractions (chromaticity, hue, saturation, normalised combinations)
are scaled by 256, their top value 256 falling into the last bin.

* :func:`rgb`: the pixels themselves (CMT's colour space).
* :func:`normalised_rg`: chromaticity ``256 (R, G) / (R + G + B)``.
* :func:`hsv`: hue, saturation, value (Fusion's target profile).
* :func:`linear_combinations`: the 49 features ``a R + b G + c B`` of Collins, Liu and
  Leordeanu (2005), used by the Hierarchical tracker (Sec. 5.2).
"""

from __future__ import annotations

import itertools
import math

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

#: Top of the channel scale: 8-bit intensities are in ``[0, 255]``, fractions are times this.
SCALE = 256.0


def rgb(pixels: Float[Array, "*shape 3"]) -> Float[Array, "*shape 3"]:
    """The RGB channels unchanged (a colour space like the others, for injection)."""
    return pixels


def normalised_rg(pixels: Float[Array, "*shape 3"]) -> Float[Array, "*shape 2"]:
    """Chromaticity ``(r, g) = 256 (R, G) / (R + G + B)``; black maps to ``256 (1/3, 1/3)``."""
    total = jnp.sum(pixels, axis=-1, keepdims=True)
    safe = jnp.where(total > 0, total, 1.0)
    rg = jnp.where(total > 0, pixels[..., :2] / safe, 1.0 / 3.0)
    return SCALE * rg


def hsv(pixels: Float[Array, "*shape 3"]) -> Float[Array, "*shape 3"]:
    """Hue, saturation and value of the hexcone model (as Python's ``colorsys.rgb_to_hsv``).

    ``V = max(R, G, B)`` (in ``[0, 255]``), ``S = 256 (V - min) / V`` (0 when ``V = 0``),
    ``H = 256 h`` with ``h`` in ``[0, 1)``: ``(G - B) / (6 d)`` when ``R`` is the maximum,
    ``(2 + (B - R) / d) / 6`` when ``G`` is, ``(4 + (R - G) / d) / 6`` otherwise, modulo 1,
    ``d = V - min``; grey pixels (``d = 0``) have hue 0.
    """
    red, green, blue = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    value = jnp.max(pixels, axis=-1)
    spread = value - jnp.min(pixels, axis=-1)
    safe_spread = jnp.where(spread > 0, spread, 1.0)
    sector = jnp.where(
        red == value,
        (green - blue) / safe_spread,
        jnp.where(
            green == value, 2.0 + (blue - red) / safe_spread, 4.0 + (red - green) / safe_spread
        ),
    )
    hue = jnp.where(spread > 0, jnp.mod(sector / 6.0, 1.0), 0.0)
    saturation = jnp.where(value > 0, spread / jnp.where(value > 0, value, 1.0), 0.0)
    return jnp.stack([SCALE * hue, SCALE * saturation, value], axis=-1)


def _linear_combination_weights() -> np.ndarray:
    """The 49 coefficient triples ``(a, b, c)``, ``a, b, c in {-2, ..., 2}``, one per line.

    Of the 124 non-zero triples, those that are multiples ``k (a, b, c)`` of another
    (``k = -1`` or ``2``) give the same feature up to sign and scale; Collins et al. keep one
    per line through the origin: the triples with ``gcd(|a|, |b|, |c|) = 1`` whose first
    non-zero entry is positive.
    """
    kept = []
    for triple in itertools.product(range(-2, 3), repeat=3):
        nonzero = [t for t in triple if t != 0]
        if nonzero and math.gcd(*(abs(t) for t in nonzero)) == 1 and nonzero[0] > 0:
            kept.append(triple)
    return np.array(kept, dtype=np.float32)


#: ``[49, 3]`` coefficients ``(a, b, c)`` of the Collins features, in lexicographic order.
LINEAR_COMBINATION_WEIGHTS = _linear_combination_weights()


def linear_combinations(pixels: Float[Array, "*shape 3"]) -> Float[Array, "*shape 49"]:
    """The 49 Collins features ``a R + b G + c B``, each normalised to ``[0, 256]``.

    Feature ``k`` with coefficients ``w_k`` ranges over ``[lo_k, hi_k]``,
    ``lo_k = 255 sum_c min(w_kc, 0)``, ``hi_k = 255 sum_c max(w_kc, 0)``, and is mapped
    linearly onto the channel scale: ``256 (w_k . (R, G, B) - lo_k) / (hi_k - lo_k)``
    (Hierarchical Sec. 5.2: "normalised to the range [0-255]"; 64 bins is ``lambda = 4``).
    """
    weights = jnp.asarray(LINEAR_COMBINATION_WEIGHTS)
    low = 255.0 * jnp.sum(jnp.minimum(weights, 0.0), axis=-1)
    high = 255.0 * jnp.sum(jnp.maximum(weights, 0.0), axis=-1)
    return SCALE * (pixels @ weights.T - low) / (high - low)
