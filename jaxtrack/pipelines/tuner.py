"""Gradient-based tuning of the PHD tracker's parameters with optax.

:func:`tune` minimises an :class:`~jaxtrack.tuning.objectives.Objective` over the trainable
parameters of a :class:`~jaxtrack.tuning.transforms.ParameterSpace`, in their unconstrained
space (log / logit). Each step evaluates the objective for ``num_keys`` PRNG keys in one
``jax.vmap`` and averages it; by default the keys are the same at every step (common random
numbers: the objective is then a deterministic function of the parameters, so that steps
compare parameters and not Monte Carlo noise), or fresh keys each step (``fresh_keys=True``,
stochastic gradient descent). The gradient, the optax update and the averaging run in one
jitted step; a host loop drives it with a progress bar, records the history and stops early
when an exponential moving average of the loss has not improved by a relative ``tolerance``
for ``patience`` steps. Even with fixed keys the particle filter's objective is rough
(resampling picks different ancestors as the parameters move), so the result is the average
of the last iterates in the unconstrained space (Polyak-Ruppert), not the iterate of the
lowest loss, which would select Monte Carlo luck.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array
from tqdm import tqdm

from jaxtrack.filters.phd import PHDParams
from jaxtrack.tuning.objectives import Objective, check_ground_truth
from jaxtrack.tuning.transforms import ParameterSpace, parameter_space
from jaxtrack.types import Detections, GroundTruth

#: Learning rate of the default optimiser, ``optax.adam`` (steps in log / logit units).
DEFAULT_LEARNING_RATE = 0.1
#: Factor of the exponential moving average of the loss that early stopping watches.
SMOOTHING = 0.8


class TuneResult(NamedTuple):
    """Outcome of :func:`tune`.

    Attributes:
        params: the tuned parameters: the average of the last iterates (see ``average_steps``).
        theta: their unconstrained trainable values.
        history: per evaluated step ``s`` (before its update): ``"loss"`` ``[steps]``,
            ``"grad_norm"`` ``[steps]``, the objective's metrics ``[steps]``, and
            ``"values"``, ``{name: [steps, ...]}`` the constrained trainable values.
        stop_reason: ``"converged"`` (early stopping), ``"max_steps"`` or ``"not finite"``.
        filter_runs: filter passes over the sequence (steps times keys; each pass is a
            forward and a backward run).
    """

    params: PHDParams
    theta: dict[str, Array]
    history: dict[str, Any]
    stop_reason: str
    filter_runs: int


def tune(
    objective: Objective,
    params: PHDParams,
    detections: Detections,
    key: Array,
    *,
    ground_truth: GroundTruth | None = None,
    space: ParameterSpace | None = None,
    optimizer: optax.GradientTransformation | None = None,
    num_steps: int = 100,
    num_keys: int = 4,
    fresh_keys: bool = False,
    patience: int = 20,
    tolerance: float = 1e-3,
    average_steps: int = 10,
    progress: bool = False,
    callback: Callable[[int, PHDParams], dict[str, float] | None] | None = None,
) -> TuneResult:
    """Tunes the trainable parameters of ``params`` by gradient descent on ``objective``.

    Args:
        objective: the loss (:func:`~jaxtrack.tuning.objectives.likelihood_objective` or
            :func:`~jaxtrack.tuning.objectives.supervised_objective`).
        params: the starting parameters; frozen parameters keep their values.
        detections: padded detections ``[num_frames, max_detections]``.
        key: PRNG key of the filter runs.
        ground_truth: padded ground truth of the same frames (supervised objective).
        space: the trainable parameters (default
            :data:`~jaxtrack.tuning.transforms.DEFAULT_TRAINABLE`).
        optimizer: any optax optimiser (default ``optax.adam(0.1)``).
        num_steps: the most optimisation steps, > 0.
        num_keys: keys the loss is averaged over per step, > 0.
        fresh_keys: new keys every step instead of common random numbers.
        patience: stop after this many steps without improvement of the smoothed loss
            (0: never stop early).
        tolerance: an improvement is a smoothed loss below
            ``best - tolerance * max(|best|, 1)``.
        average_steps: the result averages the unconstrained parameters of the last
            ``average_steps`` finite steps (Polyak-Ruppert averaging), > 0.
        progress: show a progress bar.
        callback: called on the host after each step with the step and the parameters
            evaluated at it; a returned dict of numbers is added to the history (e.g. a
            tracking score).

    Returns:
        The :class:`TuneResult`.

    Raises:
        ValueError: bad step, key or patience counts, or missing / mismatched ground truth
            for an objective that needs it.
        FloatingPointError: the objective or its gradient is not finite at the start.
    """
    if num_steps <= 0 or num_keys <= 0 or average_steps <= 0 or patience < 0:
        raise ValueError("num_steps, num_keys, average_steps must be positive, patience >= 0")
    if objective.needs_ground_truth:
        check_ground_truth(detections, ground_truth)
    space = space or parameter_space(params)
    optimizer = optimizer or optax.adam(DEFAULT_LEARNING_RATE)
    detections = Detections(*(jnp.asarray(leaf) for leaf in detections))
    if ground_truth is not None:
        ground_truth = GroundTruth(*(jnp.asarray(leaf) for leaf in ground_truth))

    def mean_loss(theta, keys, detections, ground_truth):
        tuned = space.to_params(theta, params)
        losses, metrics = jax.vmap(lambda k: objective.loss(tuned, k, detections, ground_truth))(
            keys
        )
        return jnp.mean(losses), jax.tree.map(jnp.mean, metrics)

    @jax.jit
    def step(theta, opt_state, keys, detections, ground_truth):
        (loss, metrics), grads = jax.value_and_grad(mean_loss, has_aux=True)(
            theta, keys, detections, ground_truth
        )
        updates, opt_state = optimizer.update(grads, opt_state, theta)
        return (
            optax.apply_updates(theta, updates),
            opt_state,
            loss,
            metrics,
            optax.tree.norm(grads),
        )

    theta = space.to_unconstrained(params)
    opt_state = optimizer.init(theta)
    key_fixed, key_fresh = jax.random.split(key)
    keys = jax.random.split(key_fixed, num_keys)
    history: dict[str, Any] = {"loss": [], "grad_norm": [], "values": {n: [] for n in theta}}
    thetas = []
    smoothed, best_smoothed, since_best = np.nan, np.inf, 0
    stop_reason = "max_steps"
    steps = range(num_steps)
    if progress:
        steps = tqdm(steps, desc=f"tuning ({objective.name})", unit="step")
    for s in steps:
        if fresh_keys:
            keys = jax.random.split(jax.random.fold_in(key_fresh, s), num_keys)
        new_theta, opt_state, loss, metrics, grad_norm = step(
            theta, opt_state, keys, detections, ground_truth
        )
        loss, grad_norm = float(loss), float(grad_norm)
        _record(history, space, theta, loss, grad_norm, metrics)
        if callback is not None:
            for name, value in (callback(s, space.to_params(theta, params)) or {}).items():
                history.setdefault(name, []).append(float(value))
        if not (np.isfinite(loss) and np.isfinite(grad_norm)):
            stop_reason = "not finite"
            break
        thetas.append(theta)
        theta = new_theta
        smoothed = loss if np.isnan(smoothed) else SMOOTHING * smoothed + (1 - SMOOTHING) * loss
        if not np.isfinite(best_smoothed) or smoothed < best_smoothed - tolerance * max(
            abs(best_smoothed), 1.0
        ):
            best_smoothed, since_best = smoothed, 0
        else:
            since_best += 1
        if progress:
            steps.set_postfix(loss=f"{loss:.4g}", smoothed=f"{smoothed:.4g}")
        if patience and since_best >= patience:
            stop_reason = "converged"
            break
    if progress:
        steps.close()
    history = _stack(history)
    if not thetas:
        raise FloatingPointError("the objective is not finite at the starting parameters")
    averaged = jax.tree.map(lambda *x: jnp.mean(jnp.stack(x), axis=0), *thetas[-average_steps:])
    return TuneResult(
        params=space.to_params(averaged, params),
        theta=averaged,
        history=history,
        stop_reason=stop_reason,
        filter_runs=len(history["loss"]) * num_keys,
    )


def _record(history, space, theta, loss, grad_norm, metrics) -> None:
    history["loss"].append(loss)
    history["grad_norm"].append(grad_norm)
    for name, value in space.values(theta).items():
        history["values"][name].append(value)
    for name, value in metrics.items():
        history.setdefault(name, []).append(float(value))


def _stack(history: dict[str, Any]) -> dict[str, Any]:
    stacked = {name: np.asarray(value) for name, value in history.items() if name != "values"}
    stacked["values"] = {name: np.asarray(v) for name, v in history["values"].items()}
    return stacked
