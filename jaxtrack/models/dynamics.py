"""Constant-velocity dynamics of a box (PHD-context Sec. III, state transition with SDV).

State ``x = (y1, vy1, y2, vy2, w, h)``: box centre, centre velocity (pixels per frame),
width and height. ``x_k = G x_{k-1} + B(x_{k-1}) n_k`` with ``G = blockdiag(A, A, I2)``,
``A = [[1, T], [0, 1]]``, ``n = (n1, n2, nw, nh)`` standard normal scaled by a
:mod:`~jaxtrack.models.noise` model: position/velocity 1 get ``[T^2/2, T] std_1 n1``,
position/velocity 2 get ``[T^2/2, T] std_2 n2``, the width ``T std_w nw`` and the height
``T std_h nh``. With the SDV noise model the standard deviations scale with the previous box
size.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from jaxtrack.models.noise import NoiseModel, state_dependent_std, std_columns

STATE_DIM = 6
#: Indices of the measured components (y1, y2, w, h) in the state (``C`` of the likelihood).
MEASURED = (0, 2, 4, 5)
#: Indices of the box centre (y1, y2) in the state.
POSITION = (0, 2)
#: Indices of the centre velocity (vy1, vy2) in the state.
VELOCITY = (1, 3)
#: Indices of the box size (w, h) in the state.
SIZE = (4, 5)
#: Smallest box width or height, pixels (keeps sizes and SDV noise positive).
MIN_SIZE = 1.0


def transition_matrix(dt: float = 1.0) -> Float[Array, "6 6"]:
    """``G = blockdiag(A, A, I2)`` with ``A = [[1, dt], [0, 1]]``."""
    block = jnp.array([[1.0, dt], [0.0, 1.0]])
    return jax.scipy.linalg.block_diag(block, block, jnp.eye(2))


def noise_gain(dt: float = 1.0) -> Float[Array, "6 4"]:
    """The constant part of ``B``: maps ``(n1, n2, nw, nh)`` (already scaled) to the state."""
    return jnp.array(
        [
            [dt**2 / 2, 0.0, 0.0, 0.0],
            [dt, 0.0, 0.0, 0.0],
            [0.0, dt**2 / 2, 0.0, 0.0],
            [0.0, dt, 0.0, 0.0],
            [0.0, 0.0, dt, 0.0],
            [0.0, 0.0, 0.0, dt],
        ]
    )


def sample_constant_velocity(
    key: Array,
    states: Float[Array, "num_particles 6"],
    noise_std: Float[Array, " 4"],
    noise_model: NoiseModel = state_dependent_std,
    normal: Float[Array, "num_particles 4"] | None = None,
) -> Float[Array, "num_particles 6"]:
    """Draws ``x_k ~ f(. | x_{k-1})`` for every particle (PHD-context eq. 9 proposal, T = 1).

    Args:
        key: PRNG key; the standard normal draws are ``jax.random.normal(key, (n, 4))``.
        states: previous states.
        noise_std: ``(std_1, std_2, std_w, std_h)`` of ``n`` (relative for SDV), positive.
        noise_model: :func:`~jaxtrack.models.noise.state_dependent_std` (SDV, default) or
            :func:`~jaxtrack.models.noise.constant_std`.
        normal: the standard normal draws, already drawn from ``key`` (None: drawn here).

    Returns:
        The predicted states; widths and heights are clipped below at
        :data:`MIN_SIZE` pixels.
    """
    if normal is None:
        normal = jax.random.normal(key, (states.shape[0], 4), states.dtype)
    # G x + B n written out per component (T = 1): the same sums as the matrix products
    # with transition_matrix() and noise_gain(), without a matrix product or a scatter.
    if rows_layout(states.shape[0]):
        scaled = noise_model(states[:, SIZE], noise_std) * normal
        y1, vy1, y2, vy2, width, height = (states[:, i] for i in range(STATE_DIM))
        n1, n2, nw, nh = (scaled[:, i] for i in range(4))
        return jnp.stack(
            [
                (y1 + vy1) + 0.5 * n1,
                vy1 + n1,
                (y2 + vy2) + 0.5 * n2,
                vy2 + n2,
                jnp.maximum(width + nw, MIN_SIZE),
                jnp.maximum(height + nh, MIN_SIZE),
            ],
            axis=0,
        ).T  # stacked as rows, then transposed: a stack along the trailing axis of 6
        # compiles to a per-element select between the six formulas (3x slower on CPU)
    # Above ROWS_MAX_PARTICLES: one elementwise expression over the [n, 6] states in their
    # own layout, (x + velocity) + noise with velocity = (vy1, -0, vy2, -0, -0, -0) (adding
    # -0 is exact) and noise = (n1 / 2, n1, n2 / 2, n2, nw, nh). Each output element reads
    # its particle's row once, where the rows form reads the states with a stride once per
    # component and writes the stacked [n, 4] standard deviations out.
    std = std_columns(noise_model, states[:, SIZE[0] : SIZE[1] + 1], noise_std)
    n1, n2, nw, nh = (std[k] * normal[:, k : k + 1] for k in range(4))
    none = jnp.full_like(states[:, :1], -0.0)
    velocity = jnp.concatenate([states[:, 1:2], none, states[:, 3:4], none, none, none], 1)
    noise = jnp.concatenate([0.5 * n1, n1, 0.5 * n2, n2, nw, nh], 1)
    lowest = jnp.array([-jnp.inf] * 4 + [MIN_SIZE] * 2, states.dtype)
    return jnp.maximum((states + velocity) + noise, lowest)


#: Particles up to which :func:`sample_constant_velocity` forms its output as ``[6, n]`` rows
#: (transposed back), above which as one elementwise expression over the ``[n, 6]`` states.
ROWS_MAX_PARTICLES = 8192


def rows_layout(num_particles: int) -> bool:
    """Whether :func:`sample_constant_velocity` forms ``num_particles`` predictions as rows.

    Both forms compute the same sums. The rows form lets a consumer that reads the states
    as rows (the PHD update's likelihood; :func:`~jaxtrack.filters.phd.join_particles`
    joins rows) cancel the transposes: at tracking sizes (2048 particles) it is the faster.
    At 1e5-1e6 particles its strided reads of the states and its written-out standard
    deviations cost more than the update's transposes: the elementwise form makes the PHD
    recursion 1.1-1.2x faster there (README, "Where the PHD step's time goes", session
    54). XLA may contract a multiply and an add of the two forms differently (a fused
    multiply-add), so they can differ by an ulp.
    """
    return num_particles <= ROWS_MAX_PARTICLES
