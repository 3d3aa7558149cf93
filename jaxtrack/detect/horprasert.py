"""Horprasert colour background model: brightness and chromaticity distortion (SPEC §4).

Horprasert, Harwood and Davis, "A statistical approach for real-time robust background
subtraction and shadow detection" (ICCV Frame-Rate Workshop 1999), as used by the
Hierarchical tracker (Sec. 4). Each pixel ``i`` has an expected colour ``E_i`` and a
per-channel spread ``s_i``. A new colour ``I_i`` is explained as ``alpha_i E_i`` plus a
residual:

* brightness distortion ``alpha_i = sum_c I_c E_c / s_c^2 / sum_c (E_c / s_c)^2`` (eq. 3,
  the ``alpha`` minimising ``sum_c ((I_c - alpha E_c) / s_c)^2``);
* chromaticity distortion ``CD_i = sqrt(sum_c ((I_c - alpha_i E_c) / s_c)^2)`` (eq. 4).

Both are normalised by their own variation over the training frames, ``a_i`` (RMS of
``alpha_i - 1``) and ``b_i`` (RMS of ``CD_i``): ``alpha^_i = (alpha_i - 1) / a_i``,
``CD^_i = CD_i / b_i`` (eq. 5-7), so that one threshold per quantity serves the whole image.
The thresholds are chosen automatically as quantiles of the normalised distortions of the
training frames (a detection rate, eq. 8), after leaving out gross outliers (people in the
training frames; :func:`trimmed`). Classes (eq. 9, with the dark-pixel bound):

* FOREGROUND: ``CD^ > tau_CD`` (a colour change);
* DARK_FOREGROUND: not FOREGROUND but ``alpha < dark_brightness`` (much darker than any
  shadow: the chromaticity of such pixels carries no information);
* BACKGROUND: ``tau_alpha_low < alpha^ < tau_alpha_high``;
* SHADOW: darker than the background (``alpha^ <= tau_alpha_low``);
* HIGHLIGHT: brighter (``alpha^ >= tau_alpha_high``).

Training frames of a busy scene contain people, so the statistics are robust: ``E`` is the
per-pixel temporal median and every spread a scaled median absolute deviation
(``1.4826 MAD``, the standard deviation for Gaussian data), floored to stay away from zero.
Everything is vectorised NumPy over the image; no per-pixel Python loop.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from jaxtrack.errors import InputError

BACKGROUND = 0
FOREGROUND = 1
DARK_FOREGROUND = 2
SHADOW = 3
HIGHLIGHT = 4
#: Class names by class number.
CLASS_NAMES = ("background", "foreground", "dark foreground", "shadow", "highlight")

#: Scale of the median absolute deviation to a Gaussian standard deviation.
MAD_TO_STD = 1.4826
#: Smallest colour spread per channel (grey levels): quantisation and compression noise.
MIN_COLOUR_STD = 2.0
#: Smallest normalising spreads of alpha and CD.
MIN_BRIGHTNESS_STD = 0.02
MIN_CHROMA_STD = 0.5
#: Training samples further than this many robust spreads from the median of all samples
#: are foreground in the training frames and left out of the automatic thresholds.
TRIM_SPREADS = 10.0


class HorprasertModel(NamedTuple):
    """The per-pixel background model and its thresholds.

    Attributes:
        mean: expected colour ``E``, ``[height, width, 3]`` float32.
        inv_std: ``1 / s`` per channel, ``[height, width, 3]`` float32.
        brightness_std: ``a``, spread of ``alpha - 1``, ``[height, width]`` float32.
        chroma_std: ``b``, spread of ``CD``, ``[height, width]`` float32.
        chroma_threshold: ``tau_CD`` on ``CD^``.
        brightness_low: ``tau_alpha_low`` (< 0) on ``alpha^``: darker is shadow.
        brightness_high: ``tau_alpha_high`` (> 0) on ``alpha^``: brighter is highlight.
        dark_brightness: raw ``alpha`` below which a pixel is dark foreground.
        scaled_mean: ``E / s`` (precomputed), ``[height, width, 3]`` float32.
        alpha_weights: ``(E / s^2) / sum_c (E_c / s_c)^2`` (precomputed), so that
            ``alpha = sum_c I_c alpha_weights_c``, ``[height, width, 3]`` float32.
    """

    mean: np.ndarray
    inv_std: np.ndarray
    brightness_std: np.ndarray
    chroma_std: np.ndarray
    chroma_threshold: float
    brightness_low: float
    brightness_high: float
    dark_brightness: float
    scaled_mean: np.ndarray
    alpha_weights: np.ndarray


def colour_terms(mean: np.ndarray, inv_std: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(E / s, alpha_weights)`` of a colour model (see :class:`HorprasertModel`)."""
    scaled_mean = (mean * inv_std).astype(np.float32)
    norm = np.maximum(np.sum(scaled_mean**2, axis=-1, keepdims=True), 1e-6)
    return scaled_mean, (scaled_mean * inv_std / norm).astype(np.float32)


def distortions(
    scaled_mean: np.ndarray, alpha_weights: np.ndarray, inv_std: np.ndarray, frames: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Brightness and chromaticity distortion of frames against a colour model (eq. 3-4).

    Args:
        scaled_mean: ``E / s``, ``[height, width, 3]`` (see :func:`colour_terms`).
        alpha_weights: ``alpha``'s per-channel weights, ``[height, width, 3]``.
        inv_std: ``1 / s``, ``[height, width, 3]``.
        frames: ``[..., height, width, 3]`` colours (any numeric type).

    Returns:
        ``(alpha, cd)``, each ``[..., height, width]`` float32.
    """
    colours = frames.astype(np.float32)
    alpha = np.einsum("...c,...c->...", colours, alpha_weights)
    residual = colours * inv_std - alpha[..., None] * scaled_mean
    cd = np.sqrt(np.einsum("...c,...c->...", residual, residual))
    return alpha, cd


def fit_horprasert(
    frames: np.ndarray,
    detection_rate: float = 0.995,
    dark_brightness: float = 0.4,
) -> HorprasertModel:
    """Learns the background model from training frames.

    Args:
        frames: ``[num_frames, height, width, 3]`` training frames (at least 3).
        detection_rate: fraction of the training pixels' normalised distortions that the
            automatic thresholds classify as background (eq. 8): ``tau_CD`` is that quantile
            of ``CD^``, ``tau_alpha_low`` / ``tau_alpha_high`` the lower / upper
            ``(1 -+ detection_rate) / 2`` quantiles of ``alpha^``.
        dark_brightness: raw brightness ratio below which a pixel is dark foreground (a
            shadow keeps a good part of the background's brightness).

    Returns:
        The model.

    Raises:
        InputError: fewer than 3 frames, not ``[N, H, W, 3]``, or a rate outside (0, 1).
    """
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.shape[-1] != 3 or frames.shape[0] < 3:
        raise InputError(f"need at least 3 training frames [N, H, W, 3], got {frames.shape}")
    if not 0 < detection_rate < 1:
        raise InputError(f"detection_rate must lie in (0, 1), got {detection_rate}")
    colours = frames.astype(np.float32)
    mean = np.median(colours, axis=0)
    spread = MAD_TO_STD * np.median(np.abs(colours - mean), axis=0)
    inv_std = (1.0 / np.maximum(spread, MIN_COLOUR_STD)).astype(np.float32)
    scaled_mean, alpha_weights = colour_terms(mean, inv_std)
    alpha, cd = distortions(scaled_mean, alpha_weights, inv_std, frames)
    brightness_std = np.maximum(
        MAD_TO_STD * np.median(np.abs(alpha - 1.0), axis=0), MIN_BRIGHTNESS_STD
    )
    chroma_std = np.maximum(MAD_TO_STD * np.median(cd, axis=0), MIN_CHROMA_STD)
    norm_alpha = (alpha - 1.0) / brightness_std
    norm_cd = cd / chroma_std
    tail = (1.0 - detection_rate) / 2
    low, high = np.quantile(trimmed(norm_alpha), [tail, 1.0 - tail])
    return HorprasertModel(
        mean=mean.astype(np.float32),
        inv_std=inv_std.astype(np.float32),
        brightness_std=brightness_std.astype(np.float32),
        chroma_std=chroma_std.astype(np.float32),
        chroma_threshold=float(np.quantile(trimmed(norm_cd), detection_rate)),
        brightness_low=float(min(low, -1e-3)),
        brightness_high=float(max(high, 1e-3)),
        dark_brightness=float(dark_brightness),
        scaled_mean=scaled_mean,
        alpha_weights=alpha_weights,
    )


def trimmed(values: np.ndarray, spreads: float = TRIM_SPREADS) -> np.ndarray:
    """The values within ``spreads`` robust spreads (1.4826 MAD) of their median.

    Training frames of a busy scene hold people; their pixels are gross outliers of the
    per-pixel statistics and would otherwise set the automatic thresholds.
    """
    values = values.reshape(-1)
    centre = np.median(values)
    spread = MAD_TO_STD * np.median(np.abs(values - centre))
    return values[np.abs(values - centre) <= spreads * max(spread, 1e-6)]


def classify(model: HorprasertModel, frame: np.ndarray) -> np.ndarray:
    """Classifies every pixel of a frame (eq. 9).

    Args:
        model: the background model.
        frame: ``[height, width, 3]`` colours, the size of the model.

    Returns:
        ``[height, width]`` uint8 class numbers (:data:`BACKGROUND`, :data:`FOREGROUND`,
        :data:`DARK_FOREGROUND`, :data:`SHADOW`, :data:`HIGHLIGHT`).

    Raises:
        InputError: the frame's shape differs from the model's.
    """
    if frame.shape != model.mean.shape:
        raise InputError(f"frame is {frame.shape} but the background model is {model.mean.shape}")
    alpha, cd = distortions(model.scaled_mean, model.alpha_weights, model.inv_std, frame)
    norm_alpha = (alpha - 1.0) / model.brightness_std
    classes = np.where(norm_alpha < 0, SHADOW, HIGHLIGHT).astype(np.uint8)
    classes[(norm_alpha > model.brightness_low) & (norm_alpha < model.brightness_high)] = BACKGROUND
    classes[alpha < model.dark_brightness] = DARK_FOREGROUND
    classes[cd > model.chroma_threshold * model.chroma_std] = FOREGROUND
    return classes


def foreground_mask(classes: np.ndarray) -> np.ndarray:
    """Foreground and dark foreground fused (the Hierarchical paper's blob input)."""
    return (classes == FOREGROUND) | (classes == DARK_FOREGROUND)
