"""Fusion's tracking-by-classification pool member: one MOSSE correlation filter per target.

The target-specific online classifier of Fusion (paper Sec. 3.2, "Tracking by
Classification"; SPEC section 3, "classification-based (per-target template classifier,
learning rate)"), realised as the Minimum Output Sum of Squared Error filter of Bolme et al.
(CVPR 2010). Every target slot of a fixed table ``[S]`` holds a filter in the Fourier domain;
all the stages ``vmap`` over the slots with one shape.

**Search window.** Around a box with centre ``(cx, cy)`` and size ``(w, h)`` the window is
``s`` times the box (``s`` = ``search_scale``), sampled bilinearly on a fixed ``ph x pw`` grid
(:func:`jaxtrack.appearance.patches.sample_patch`), cell size ``(c_x, c_y) = (s w / pw,
s h / ph)``, placed so that the grid point ``(ph // 2, pw // 2)`` lies on the box centre.
Samples outside the image take the nearest border pixel's value.

**Features** (Bolme Sec. 3.1): grey level ``I = 0.299 R + 0.587 G + 0.114 B``,
``f = log(1 + I)``, normalised to zero mean and unit energy (``sum f^2 = 1``, so that the mean
spectral power ``mean |F|^2`` is 1 by Parseval and the regulariser is relative to it), then
multiplied by the cosine (Hann) window ``c(i, j) = sin^2(pi i / (ph - 1)) sin^2(pi j /
(pw - 1))``.

**Filter** (Bolme eqs. 10-12): desired output ``g(i, j) = exp(-((i - ph//2)^2 + (j -
pw//2)^2) / (2 sigma^2))`` (``sigma`` in grid cells), ``G = FFT(g)``, ``F = FFT(f)``;

    A_t = (1 - lambda) A_{t-1} + lambda G . conj(F_t),
    B_t = (1 - lambda) B_{t-1} + lambda F_t . conj(F_t),
    H*_t = A_t / (B_t + epsilon),

started from ``A_0 = G . conj(F_0)``, ``B_0 = F_0 . conj(F_0)`` on the first box (one
template; Bolme trains on eight affine perturbations of it, not done here), ``lambda`` the
paper's learning rate (0.15 CAVIAR, 0.35 PETS 2009, SPEC section 3) and ``epsilon`` the
regularisation.

**Localisation**: the response on the window around the previous box is
``R = real(IFFT(F . H*))`` (``ph x pw``); its peak ``(i*, j*)``, refined to sub-cell precision
by a parabola through the peak and its two neighbours on each axis
(``delta = (r_- - r_+) / (2 (r_- - 2 r_0 + r_+))``, clipped to ``[-1/2, 1/2]``), moves the
centre by ``((j* + delta_j - pw//2) c_x, (i* + delta_i - ph//2) c_y)``; the size is kept.
**Confidence**: the peak-to-sidelobe ratio (Bolme Sec. 3.2) ``PSR = (max R - mu) / sigma_sl``,
``mu, sigma_sl`` the mean and standard deviation of ``R`` outside the ``11 x 11`` cells around
the peak.

The filter is then updated on the window around the new box, only in the slots of
``update_mask`` (Fusion eq. 2's occluded targets keep their filter frozen; paper Sec. 2).
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
from jaxtyping import Array, Bool, Complex, Float, UInt8

from jaxtrack.appearance.patches import check_frame, sample_patch
from jaxtrack.errors import InputError
from jaxtrack.types import PAD_BOX

#: Default ``(ph, pw)`` of the search window's sample grid.
CLASSIFIER_PATCH_SHAPE = (32, 32)
#: Half-width (cells) of the square around the response peak excluded from the PSR sidelobe.
PSR_EXCLUSION = 5
_GREY = (0.299, 0.587, 0.114)


class ClassifierParams(NamedTuple):
    """Parameters of the correlation-filter classifier (float32 scalars).

    Attributes:
        learning_rate: ``lambda`` in ``[0, 1]``, the weight of the new template.
        sigma: standard deviation of the desired Gaussian response, grid cells.
        regularisation: ``epsilon`` added to ``B`` (relative to the mean spectral power 1).
        search_scale: ``s``, the search window's size as a multiple of the box's (>= 1).
    """

    learning_rate: Float[Array, ""]
    sigma: Float[Array, ""]
    regularisation: Float[Array, ""]
    search_scale: Float[Array, ""]


class ClassifierState(NamedTuple):
    """One filter per target slot.

    Attributes:
        numerator: ``A``, complex64 ``[S, ph, pw]``.
        denominator: ``B`` (real: ``F conj(F)`` is), float32 ``[S, ph, pw]``.
        boxes: ``(x, y, w, h)`` of each target, float32 ``[S, 4]``; ``PAD_BOX`` in dead slots.
        alive: which slots hold a target, bool ``[S]``.
    """

    numerator: Complex[Array, "max_targets ph pw"]
    denominator: Float[Array, "max_targets ph pw"]
    boxes: Float[Array, "max_targets 4"]
    alive: Bool[Array, " max_targets"]


class ClassifierResponse(NamedTuple):
    """What one step saw (the fusion's ``R_i``).

    Attributes:
        response: ``R`` on each slot's search window, float32 ``[S, ph, pw]``; grid point
            ``(i, j)`` lies at ``(window_x + (j + 1/2) c_x, window_y + (i + 1/2) c_y)``.
        windows: the search windows ``(x, y, pw c_x, ph c_y)``, float32 ``[S, 4]``.
        psr: peak-to-sidelobe ratio, float32 ``[S]`` (0 in dead slots).
    """

    response: Float[Array, "max_targets ph pw"]
    windows: Float[Array, "max_targets 4"]
    psr: Float[Array, " max_targets"]


def classifier_params(
    learning_rate: float = 0.35,
    sigma: float = 1.0,
    regularisation: float = 0.01,
    search_scale: float = 2.0,
) -> ClassifierParams:
    """Validated parameters; the default learning rate is the paper's for PETS 2009.

    Raises:
        InputError: ``learning_rate`` outside ``[0, 1]``, ``sigma`` or ``regularisation`` not
            positive, or ``search_scale`` below 1.
    """
    if not 0.0 <= learning_rate <= 1.0:
        raise InputError(f"learning_rate must lie in [0, 1], got {learning_rate}")
    if not (sigma > 0.0 and regularisation > 0.0):
        raise InputError(
            f"sigma and regularisation must be positive, got {sigma} and {regularisation}"
        )
    if not search_scale >= 1.0:
        raise InputError(f"search_scale must be at least 1, got {search_scale}")
    values = (learning_rate, sigma, regularisation, search_scale)
    return ClassifierParams(*(jnp.asarray(v, jnp.float32) for v in values))


def search_window(
    box: Float[Array, " 4"], search_scale: Float[Array, ""], patch_shape: tuple[int, int]
) -> Float[Array, " 4"]:
    """The window ``s`` times ``box`` whose grid point ``(ph // 2, pw // 2)`` is its centre.

    Returns:
        ``(cx - (pw//2 + 1/2) c_x, cy - (ph//2 + 1/2) c_y, pw c_x, ph c_y)``.
    """
    rows, cols = patch_shape
    cell_x = search_scale * box[2] / cols
    cell_y = search_scale * box[3] / rows
    cx, cy = box[0] + box[2] / 2, box[1] + box[3] / 2
    return jnp.stack(
        [
            cx - (cols // 2 + 0.5) * cell_x,
            cy - (rows // 2 + 0.5) * cell_y,
            cols * cell_x,
            rows * cell_y,
        ]
    )


def window_features(
    frame: UInt8[Array, "height width 3"], window: Float[Array, " 4"], patch_shape
) -> Float[Array, "ph pw"]:
    """``f``: log grey level on the window's grid, zero mean, unit energy, Hann-windowed."""
    grey = sample_patch(frame, window, patch_shape).values @ jnp.asarray(_GREY, jnp.float32)
    f = jnp.log1p(grey)
    f = f - f.mean()
    f = f / jnp.sqrt(jnp.maximum(jnp.sum(f * f), 1e-12))
    rows, cols = patch_shape
    hann_y = jnp.sin(jnp.pi * jnp.arange(rows) / (rows - 1)) ** 2
    hann_x = jnp.sin(jnp.pi * jnp.arange(cols) / (cols - 1)) ** 2
    return f * hann_y[:, None] * hann_x[None, :]


def desired_response(sigma: Float[Array, ""], patch_shape) -> Float[Array, "ph pw"]:
    """``g``: a Gaussian of standard deviation ``sigma`` cells peaked at ``(ph//2, pw//2)``."""
    rows, cols = patch_shape
    di = (jnp.arange(rows) - rows // 2)[:, None]
    dj = (jnp.arange(cols) - cols // 2)[None, :]
    return jnp.exp(-(di**2 + dj**2) / (2.0 * sigma**2)).astype(jnp.float32)


def filter_terms(
    features: Float[Array, "ph pw"], sigma: Float[Array, ""]
) -> tuple[Complex[Array, "ph pw"], Float[Array, "ph pw"]]:
    """One template's ``(G conj(F), F conj(F))`` (Bolme eqs. 10-11 before averaging)."""
    spectrum = jnp.fft.fft2(features)
    target = jnp.fft.fft2(desired_response(sigma, features.shape))
    return target * jnp.conj(spectrum), jnp.real(spectrum * jnp.conj(spectrum))


def correlate(
    numerator: Complex[Array, "ph pw"],
    denominator: Float[Array, "ph pw"],
    features: Float[Array, "ph pw"],
    regularisation: Float[Array, ""],
) -> Float[Array, "ph pw"]:
    """``R = real(IFFT(F . A / (B + epsilon)))`` (Bolme eq. 1 with ``H* = A / B``)."""
    spectrum = jnp.fft.fft2(features)
    return jnp.real(jnp.fft.ifft2(spectrum * numerator / (denominator + regularisation)))


def peak_offset(response: Float[Array, "ph pw"]) -> Float[Array, " 2"]:
    """The sub-cell peak minus ``(ph//2, pw//2)``, ``(d_row, d_col)``, parabola-refined."""
    rows, cols = response.shape
    flat = jnp.argmax(response)
    i, j = flat // cols, flat % cols

    def refine(minus, centre, plus):
        curvature = minus - 2.0 * centre + plus
        safe = jnp.where(curvature < 0, curvature, -1.0)
        return jnp.where(curvature < 0, jnp.clip((minus - plus) / (2.0 * safe), -0.5, 0.5), 0.0)

    centre = response[i, j]
    d_row = refine(response[(i - 1) % rows, j], centre, response[(i + 1) % rows, j])
    d_col = refine(response[i, (j - 1) % cols], centre, response[i, (j + 1) % cols])
    return jnp.stack([i + d_row - rows // 2, j + d_col - cols // 2]).astype(jnp.float32)


def peak_to_sidelobe(response: Float[Array, "ph pw"]) -> Float[Array, ""]:
    """``PSR = (max R - mu) / sigma_sl`` over the cells outside the ``11 x 11`` peak square."""
    rows, cols = response.shape
    flat = jnp.argmax(response)
    i, j = flat // cols, flat % cols
    near = (jnp.abs(jnp.arange(rows) - i) <= PSR_EXCLUSION)[:, None] & (
        jnp.abs(jnp.arange(cols) - j) <= PSR_EXCLUSION
    )[None, :]
    side = ~near
    count = jnp.sum(side)
    mean = jnp.sum(jnp.where(side, response, 0.0)) / count
    var = jnp.sum(jnp.where(side, (response - mean) ** 2, 0.0)) / count
    return (response[i, j] - mean) / jnp.sqrt(jnp.maximum(var, 1e-20))


def init_classifier(
    frame: UInt8[Array, "height width 3"],
    boxes: Float[Array, "max_targets 4"],
    alive: Bool[Array, " max_targets"],
    params: ClassifierParams,
    patch_shape: tuple[int, int] = CLASSIFIER_PATCH_SHAPE,
) -> ClassifierState:
    """Trains one filter per live slot on ``frame``: ``A_0 = G conj(F_0)``, ``B_0 = |F_0|^2``.

    Args:
        frame: RGB frame, uint8.
        boxes: ``(x, y, w, h)`` per slot; dead slots' values are ignored.
        alive: which slots hold a target.
        params: :class:`ClassifierParams`.
        patch_shape: ``(ph, pw)`` of the window's grid, static, each at least 2x
            ``PSR_EXCLUSION + 1`` so that the PSR has a sidelobe.

    Raises:
        InputError: a bad frame, ``boxes`` not ``[S, 4]``, ``alive`` not ``[S]`` or a grid
            too small.
    """
    _check_inputs(frame, boxes, alive, "alive")
    rows, cols = patch_shape
    if min(rows, cols) <= 2 * PSR_EXCLUSION + 1:
        raise InputError(f"patch_shape must exceed {2 * PSR_EXCLUSION + 1}, got {patch_shape}")
    empty = ClassifierState(
        jnp.zeros((boxes.shape[0], rows, cols), jnp.complex64),
        jnp.zeros((boxes.shape[0], rows, cols), jnp.float32),
        jnp.broadcast_to(jnp.asarray(PAD_BOX, jnp.float32), boxes.shape),
        jnp.zeros(boxes.shape[0], bool),
    )
    return start_targets(empty, frame, boxes, alive, params)


def start_targets(
    state: ClassifierState,
    frame: UInt8[Array, "height width 3"],
    boxes: Float[Array, "max_targets 4"],
    start_mask: Bool[Array, " max_targets"],
    params: ClassifierParams,
) -> ClassifierState:
    """(Re)starts the slots of ``start_mask`` on ``boxes`` in ``frame`` (a new target).

    The other slots are returned unchanged.
    """
    _check_inputs(frame, boxes, start_mask, "start_mask")
    patch_shape = state.numerator.shape[1:]
    safe = jnp.where(start_mask[:, None], boxes.astype(jnp.float32), jnp.asarray(PAD_BOX))

    def train(box):
        window = search_window(box, params.search_scale, patch_shape)
        return filter_terms(window_features(frame, window, patch_shape), params.sigma)

    numerator, denominator = jax.vmap(train)(safe)
    keep = start_mask[:, None, None]
    return ClassifierState(
        jnp.where(keep, numerator, state.numerator),
        jnp.where(keep, denominator, state.denominator),
        jnp.where(start_mask[:, None], safe, state.boxes),
        state.alive | start_mask,
    )


def classifier_step(
    state: ClassifierState,
    frame: UInt8[Array, "height width 3"],
    params: ClassifierParams,
    update_mask: Bool[Array, " max_targets"],
) -> tuple[ClassifierState, ClassifierResponse]:
    """Localises every live target in ``frame``, then updates the filters of ``update_mask``.

    Per live slot: response ``R`` on the window around the previous box, new centre from its
    sub-cell peak (size kept), PSR; then ``A, B`` blended with the new box's template at
    rate ``lambda`` where ``update_mask`` (and alive). Dead slots are returned unchanged with
    a zero response and PSR.

    Args:
        state: :class:`ClassifierState` of the previous frame.
        frame: RGB frame, uint8.
        params: :class:`ClassifierParams`.
        update_mask: slots whose filter learns from this frame (not occluded).

    Returns:
        The new state and the :class:`ClassifierResponse`.
    """
    _check_inputs(frame, state.boxes, update_mask, "update_mask")
    patch_shape = state.numerator.shape[1:]
    rate = params.learning_rate

    def one(numerator, denominator, box, alive, update):
        window = search_window(box, params.search_scale, patch_shape)
        response = correlate(
            numerator,
            denominator,
            window_features(frame, window, patch_shape),
            params.regularisation,
        )
        d_row, d_col = peak_offset(response)
        cell_x, cell_y = window[2] / patch_shape[1], window[3] / patch_shape[0]
        moved = box + jnp.stack([d_col * cell_x, d_row * cell_y, 0.0, 0.0])
        new_window = search_window(moved, params.search_scale, patch_shape)
        a, b = filter_terms(window_features(frame, new_window, patch_shape), params.sigma)
        learn = alive & update
        numerator = jnp.where(learn, (1 - rate) * numerator + rate * a, numerator)
        denominator = jnp.where(learn, (1 - rate) * denominator + rate * b, denominator)
        psr = jnp.where(alive, peak_to_sidelobe(response), 0.0)
        return (
            numerator,
            denominator,
            jnp.where(alive, moved, box),
            jnp.where(alive, response, 0.0),
            window,
            psr,
        )

    numerator, denominator, boxes, response, windows, psr = jax.vmap(one)(
        state.numerator, state.denominator, state.boxes, state.alive, update_mask
    )
    return (
        ClassifierState(numerator, denominator, boxes, state.alive),
        ClassifierResponse(response, windows, psr),
    )


def _check_inputs(frame, boxes, mask, mask_name: str) -> None:
    check_frame(frame)
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        raise InputError(f"boxes must be [S, 4], got shape {boxes.shape}")
    if mask.shape != boxes.shape[:1] or mask.dtype != bool:
        raise InputError(
            f"{mask_name} must be a bool [S] array, S = {boxes.shape[0]}, got "
            f"{mask.dtype} {mask.shape}"
        )
