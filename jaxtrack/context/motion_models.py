"""Local motion models: per-cell Gaussian-process regression on training tracklets.

Fusion Sec. 3.2, "Tracking by Motion prediction" (SPEC section 3): the training trajectories
are cut into tracklets of ``N_tracklet`` points, the informative ones kept, and the dominant
ones of each neighbourhood modelled by Gaussian-process regression. The choices the paper
leaves open, made here (each a parameter):

* **Point.** A box's foot point ``(x + w / 2, y + h)``
  (:func:`~jaxtrack.context.activity.foot_points`), the point the activity mask and the
  entry/exit zones are made of: where a person stands on the ground, steadier than the box
  centre under a changing box height.
* **Tracklets.** Each trajectory, cut where a frame is missing, is divided into
  consecutive non-overlapping windows of ``N + 1`` foot points (the paper's "divided into
  smaller tracklets"): the first ``N`` points are the tracklet, the last the point to
  predict. Overlapping windows (stride 1) fill a cell with near copies of one person's
  walk, whose correlated residuals the model then fits: on PETS09-S2L1 (train frames
  1-397, test 398-795) they left the GP 6% behind its own constant-velocity prior mean on
  the held-out tracklets (0.872 vs 0.820 pixels, all 2203 stride-1 test windows),
  non-overlapping ones 1% behind (0.879 vs 0.871 on the 371 non-overlapping test windows,
  ``benchmarks/fusion_motion.py``).
* **Informative.** A tracklet whose displacement ``|p_N - p_1|`` is at least
  ``min_displacement`` pixels (a standing person carries no motion pattern).
* **Neighbourhood.** A fixed grid of square cells of side ``cell_size`` pixels over the
  image; a tracklet belongs to the cell of its last point (clipped to the grid). A cell with
  fewer than ``min_tracklets`` informative tracklets has no model (constant velocity).
* **Regression.** Input ``u = (v_2, ..., v_N)`` flattened, the ``N - 1`` velocities
  ``v_k = p_k - p_{k-1}`` (pixels per frame); output the next displacement
  ``d = p_{N+1} - p_N``. The GP has the constant-velocity prior mean
  ``m(u) = (p_N - p_1) / (N - 1)``, the tracklet's mean velocity (on PETS09-S2L1 gt it
  predicts the next foot point 6% better than the last velocity ``v_N``: 0.871 vs 0.931
  pixels), and models the residual ``r = d - m(u)`` (two outputs sharing one kernel): far
  from the training tracklets the prediction falls back to constant velocity. Kernel
  ``k(u, u') = s^2 exp(-|u - u'|^2 / (2 l^2))`` plus noise ``sigma^2`` on the diagonal
  (tinygp's ``ExpSquared``).
* **Hyperparameters.** Shared by all cells, chosen by type-II maximum likelihood on a
  grid: the prior variance of a residual ``s^2 + sigma^2 = V``, the mean squared residual
  per axis of the informative tracklets, is split as ``sigma^2 = f V``, ``s^2 = (1 - f) V``;
  ``(l, f)`` maximises the summed log marginal likelihood of the cells' residuals
  (R&W eq. 2.30; both axes, padded slots contribute nothing) over ``l`` in
  ``LENGTH_SCALE_FACTORS`` times the median distance between the inputs of informative
  tracklets and ``f`` in ``NOISE_FRACTIONS``.
* **Fixed size.** At most ``max_points`` tracklets per cell (evenly spaced in the cell's
  list when there are more): every cell's model is padded to ``K = max_points`` slots with
  a mask, and its Cholesky factor ``L`` of ``K_y = K + sigma^2 I`` (identity on padded
  slots) and ``alpha = K_y^-1 r`` (zero on padded slots) are computed once here, so that a
  prediction is a kernel row times ``alpha`` (Rasmussen & Williams 2006, Alg. 2.1).

Fitting is host-side NumPy (JAX for the batched Cholesky); the per-frame prediction is
:func:`jaxtrack.filters.fusion_motion.predict_motion`.
"""

from __future__ import annotations

from typing import NamedTuple

import jax
import jax.numpy as jnp
import jax.scipy.linalg as jsl
import numpy as np
import tinygp
from jaxtyping import Array, Bool, Float, Int

from jaxtrack.context.activity import foot_points, grid_shape
from jaxtrack.errors import InputError
from jaxtrack.types import MotTable

#: ``N_tracklet``: points of a tracklet fed to the predictor.
TRACKLET_LENGTH = 5
#: Side of a grid cell, pixels.
CELL_SIZE = 96.0
#: Smallest displacement over a tracklet that makes it informative, pixels.
MIN_DISPLACEMENT = 4.0
#: Fewest informative tracklets of a cell that give it a model.
MIN_TRACKLETS = 8
#: ``K``: most tracklets kept per cell (the padded model size).
MAX_POINTS = 64
#: Candidate length scales, as multiples of the median distance between inputs.
LENGTH_SCALE_FACTORS = (1 / 16, 1 / 8, 1 / 4, 1 / 2, 1.0)
#: Candidate shares ``f`` of the residual variance that is noise.
NOISE_FRACTIONS = (0.1, 0.3, 0.5, 0.7, 0.9)


class MotionModels(NamedTuple):
    """Per-cell GP models of the next displacement, padded to a fixed size (a PyTree).

    Attributes:
        inputs: ``[cells, K, 2 (N - 1)]`` training inputs ``u`` (zero on padded slots).
        mask: ``[cells, K]`` True on real training tracklets.
        alpha: ``[cells, K, 2]`` ``K_y^-1 r`` (zero on padded slots).
        cholesky: ``[cells, K, K]`` lower Cholesky factor of ``K_y`` (identity on padded
            slots).
        fitted: ``[cells]`` True for a cell with a model, False for constant velocity.
        length_scale: ``l``, pixels per frame.
        amplitude: ``s^2``, pixels^2.
        noise: ``sigma^2``, pixels^2.
        cell_size: grid cell side, pixels (cell ``i * columns + j`` covers
            ``[j c, (j + 1) c) x [i c, (i + 1) c)``).
        grid: ``[2]`` ``(rows, columns)`` of the grid.
    """

    inputs: Float[Array, "cells K features"]
    mask: Bool[Array, "cells K"]
    alpha: Float[Array, "cells K 2"]
    cholesky: Float[Array, "cells K K"]
    fitted: Bool[Array, " cells"]
    length_scale: Float[Array, ""]
    amplitude: Float[Array, ""]
    noise: Float[Array, ""]
    cell_size: Float[Array, ""]
    grid: Int[Array, " 2"]


class Tracklets(NamedTuple):
    """Windows of consecutive foot points of the training trajectories.

    Attributes:
        points: ``[num_tracklets, N, 2]`` the tracklets' foot points, oldest first.
        next_points: ``[num_tracklets, 2]`` the point that followed each tracklet.
    """

    points: np.ndarray
    next_points: np.ndarray


def motion_kernel(length_scale: Float[Array, ""], amplitude: Float[Array, ""]):
    """``k(u, u') = s^2 exp(-|u - u'|^2 / (2 l^2))`` as a tinygp kernel (jit-able)."""
    return amplitude * tinygp.kernels.ExpSquared(scale=length_scale)


def tracklet_inputs(points: Float[Array, "*batch N 2"]) -> Float[Array, "*batch features"]:
    """``u = (v_2, ..., v_N)``, ``v_k = p_k - p_{k-1}``, flattened (works on NumPy and JAX)."""
    velocities = points[..., 1:, :] - points[..., :-1, :]
    return velocities.reshape(*velocities.shape[:-2], velocities.shape[-2] * velocities.shape[-1])


def mean_velocity(points: Float[Array, "*batch N 2"]) -> Float[Array, "*batch 2"]:
    """``m(u) = (p_N - p_1) / (N - 1)``, the constant-velocity prior mean (NumPy or JAX)."""
    return (points[..., -1, :] - points[..., 0, :]) / (points.shape[-2] - 1)


def cut_tracklets(table: MotTable, length: int = TRACKLET_LENGTH) -> Tracklets:
    """Consecutive non-overlapping windows of ``length + 1`` foot points of each trajectory.

    Args:
        table: trajectories (gt or a tracker's output): frames, ids, boxes.
        length: ``N``, points per tracklet (at least 2).

    Returns:
        The tracklets and the point following each, trajectory by trajectory.

    Raises:
        InputError: ``length < 2``, or a trajectory with two boxes in one frame.
    """
    if length < 2:
        raise InputError(f"tracklet length must be >= 2, got {length}")
    frames = np.asarray(table.frames, np.int64)
    ids = np.asarray(table.ids, np.int64)
    order = np.lexsort((frames, ids))
    frames, ids, feet = frames[order], ids[order], foot_points(table.boxes)[order]
    repeated = (ids[1:] == ids[:-1]) & (frames[1:] == frames[:-1])
    if repeated.any():
        at = int(np.flatnonzero(repeated)[0]) + 1
        line = int(np.asarray(table.lines)[order][at])
        where = f"{table.path or 'table'}" + (f", line {line}" if line > 0 else "")
        raise InputError(f"{where}: id {ids[at]} has two boxes in frame {frames[at]}")
    window = length + 1
    if frames.size < window:
        return Tracklets(np.zeros((0, length, 2)), np.zeros((0, 2)))
    steps = (ids[1:] == ids[:-1]) & (frames[1:] == frames[:-1] + 1)
    run_start = np.maximum.accumulate(np.where(np.r_[False, steps], 0, np.arange(frames.size)))
    first = (np.arange(frames.size) - run_start) % window == 0
    run_ok = np.lib.stride_tricks.sliding_window_view(steps, window - 1).all(axis=1)
    starts = run_ok & first[: run_ok.size]
    windows = np.lib.stride_tricks.sliding_window_view(feet, window, axis=0)[starts]
    windows = np.moveaxis(windows, -1, 1)
    return Tracklets(points=windows[:, :length], next_points=windows[:, length])


def tracklet_cells(
    points: Float[Array, "*batch 2"], cell_size: Float[Array, ""], grid: Int[Array, " 2"]
) -> Int[Array, "*batch"]:
    """Cell ``i * columns + j`` of each point, clipped to the grid (NumPy or JAX)."""
    xnp = jnp if isinstance(points, jax.Array) else np
    cells = xnp.floor(points / cell_size).astype(xnp.int32)
    row = xnp.clip(cells[..., 1], 0, grid[0] - 1)
    column = xnp.clip(cells[..., 0], 0, grid[1] - 1)
    return row * grid[1] + column


def fit_motion_models(
    tracklets: Tracklets,
    width: float,
    height: float,
    cell_size: float = CELL_SIZE,
    min_displacement: float = MIN_DISPLACEMENT,
    min_tracklets: int = MIN_TRACKLETS,
    max_points: int = MAX_POINTS,
    length_scale_factors: tuple[float, ...] = LENGTH_SCALE_FACTORS,
    noise_fractions: tuple[float, ...] = NOISE_FRACTIONS,
) -> MotionModels:
    """Per-cell GP models of the next displacement (Fusion Sec. 3.2; module docstring).

    Args:
        tracklets: training tracklets (:func:`cut_tracklets`).
        width: image width, pixels.
        height: image height, pixels.
        cell_size: grid cell side, pixels.
        min_displacement: ``|p_N - p_1|`` of an informative tracklet, pixels.
        min_tracklets: fewest informative tracklets of a cell with a model.
        max_points: ``K``, most tracklets kept per cell.
        length_scale_factors: candidate ``l`` over the median input distance.
        noise_fractions: candidate ``f = sigma^2 / (s^2 + sigma^2)``, each in ``(0, 1)``.

    Returns:
        The models (every cell constant velocity when no tracklet is informative).

    Raises:
        InputError: a non-positive size, fraction or count.
    """
    for name, value in [
        ("width", width),
        ("height", height),
        ("cell_size", cell_size),
        ("max_points", max_points),
        ("min_tracklets", min_tracklets),
    ]:
        if not value > 0:
            raise InputError(f"{name} must be > 0, got {value}")
    if not length_scale_factors or min(length_scale_factors) <= 0:
        raise InputError(f"length_scale_factors must be > 0, got {length_scale_factors}")
    if not noise_fractions or not all(0 < f < 1 for f in noise_fractions):
        raise InputError(f"noise_fractions must lie in (0, 1), got {noise_fractions}")
    points = np.asarray(tracklets.points, np.float64)
    moving = np.linalg.norm(points[:, -1] - points[:, 0], axis=1) >= min_displacement
    points, next_points = points[moving], np.asarray(tracklets.next_points)[moving]
    inputs = tracklet_inputs(points)
    residuals = next_points - points[:, -1] - mean_velocity(points)
    grid = np.array(grid_shape(width, height, cell_size))
    num_cells = int(grid.prod())
    cells = tracklet_cells(points[:, -1], cell_size, grid)
    features = inputs.shape[1]
    padded_inputs = np.zeros((num_cells, max_points, features))
    padded_residuals = np.zeros((num_cells, max_points, 2))
    mask = np.zeros((num_cells, max_points), bool)
    for cell in np.unique(cells):
        rows = np.flatnonzero(cells == cell)
        if rows.size < min_tracklets:
            continue
        kept = rows[np.linspace(0, rows.size - 1, min(rows.size, max_points)).astype(int)]
        padded_inputs[cell, : kept.size] = inputs[kept]
        padded_residuals[cell, : kept.size] = residuals[kept]
        mask[cell, : kept.size] = True
    v, median_distance = residual_scales(inputs, residuals)
    data = (jnp.asarray(padded_inputs), jnp.asarray(padded_residuals), jnp.asarray(mask))
    candidates = [
        (factor * median_distance, fraction)
        for factor in length_scale_factors
        for fraction in noise_fractions
    ]
    scores = [
        float(
            log_marginal_likelihood(*data[1:], *condition_cells(*data, scale, (1 - f) * v, f * v))
        )
        for scale, f in candidates
    ]
    length_scale, fraction = candidates[int(np.argmax(scores))]
    amplitude, noise = (1 - fraction) * v, fraction * v
    cholesky, alpha = condition_cells(*data, length_scale, amplitude, noise)
    return MotionModels(
        inputs=jnp.asarray(padded_inputs, jnp.float32),
        mask=jnp.asarray(mask),
        alpha=alpha.astype(jnp.float32),
        cholesky=cholesky.astype(jnp.float32),
        fitted=jnp.asarray(mask.any(axis=1)),
        length_scale=jnp.float32(length_scale),
        amplitude=jnp.float32(amplitude),
        noise=jnp.float32(noise),
        cell_size=jnp.float32(cell_size),
        grid=jnp.asarray(grid, jnp.int32),
    )


def residual_scales(inputs: np.ndarray, residuals: np.ndarray) -> tuple[float, float]:
    """``(V, D)``: mean squared residual per axis; median distance between inputs.

    The median is over at most 1000 evenly spaced tracklets. With fewer than two informative
    tracklets, ``V = 1`` and ``D = 1`` (no cell has a model then; ``V`` is the
    constant-velocity variance).
    """
    if inputs.shape[0] < 2:
        return 1.0, 1.0
    sample = inputs[np.linspace(0, inputs.shape[0] - 1, min(inputs.shape[0], 1000)).astype(int)]
    distances = np.linalg.norm(sample[:, None] - sample[None], axis=-1)
    length_scale = float(np.median(distances[np.triu_indices(sample.shape[0], 1)]))
    amplitude = float(np.mean(residuals**2))
    return max(amplitude, 1e-6), max(length_scale, 1e-6)


@jax.jit
def condition_cells(
    inputs: Float[Array, "cells K features"],
    residuals: Float[Array, "cells K 2"],
    mask: Bool[Array, "cells K"],
    length_scale: Float[Array, ""],
    amplitude: Float[Array, ""],
    noise: Float[Array, ""],
) -> tuple[Float[Array, "cells K K"], Float[Array, "cells K 2"]]:
    """``L = chol(K + sigma^2 I)`` and ``alpha = K_y^-1 r`` per cell (R&W Alg. 2.1).

    Padded slots: identity rows and columns of ``K_y``, zero residuals (so zero ``alpha``).
    """

    def one_cell(cell_inputs, cell_residuals, cell_mask):
        kernel = motion_kernel(length_scale, amplitude)
        pair = cell_mask[:, None] & cell_mask[None, :]
        gram = jnp.where(pair, kernel(cell_inputs, cell_inputs), 0.0)
        gram = gram + jnp.diag(jnp.where(cell_mask, noise, 1.0))
        factor = jnp.linalg.cholesky(gram)
        alpha = jsl.cho_solve((factor, True), jnp.where(cell_mask[:, None], cell_residuals, 0.0))
        return factor, alpha

    return jax.vmap(one_cell)(inputs, residuals, mask)


@jax.jit
def log_marginal_likelihood(
    residuals: Float[Array, "cells K 2"],
    mask: Bool[Array, "cells K"],
    cholesky: Float[Array, "cells K K"],
    alpha: Float[Array, "cells K 2"],
) -> Float[Array, ""]:
    """``sum over cells and axes of -r^T alpha / 2 - sum_i log L_ii - n log(2 pi) / 2``.

    R&W eq. 2.30 (Alg. 2.1); padded slots (``L_ii = 1``, ``r_i = 0``) add nothing.
    """
    fit = -0.5 * jnp.sum(jnp.where(mask[..., None], residuals, 0.0) * alpha)
    log_det = 2.0 * jnp.sum(jnp.log(jnp.diagonal(cholesky, axis1=1, axis2=2)))
    return fit - log_det - jnp.sum(mask) * jnp.log(2 * jnp.pi)
