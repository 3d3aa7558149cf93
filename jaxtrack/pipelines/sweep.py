"""Parameter sweeps: many tracker configurations in one compiled, batched, sharded call.

A sweep runs a filter (tracking, extraction and labelling, :func:`~jaxtrack.filters.base.run`)
for a batch of parameter PyTrees with ``jax.vmap`` inside one ``jax.jit``, in chunks of
``chunk_size`` configurations to bound memory, and scores every configuration against the
ground truth host-side (:func:`~jaxtrack.metrics.evaluate.evaluate_sequence`: MOTA, MOTP,
MODA, MODP, IDF1, HOTA, ...; no files written). The batch axis of each chunk is sharded over
all visible JAX devices (``NamedSharding(Mesh(devices, ("batch",)), PartitionSpec("batch"))``),
so the same call uses one CPU, several forced host devices
(``XLA_FLAGS=--xla_force_host_platform_device_count=N``), several GPUs, or several hosts after
``jax.distributed.initialize()``. The host scores a chunk while the devices run the next.

Batches are built from a base parameter PyTree and ``updates``, a mapping from parameter
names to one value per configuration (:func:`batch_params`). The names are those of the
tracker's parameter-properties tree (:mod:`jaxtrack.parameters`,
:data:`~jaxtrack.filters.registry.TRACKERS`), the same names the tuner and the tracker
configuration use (``"clutter_rate"`` is ``lambda_r``, ``"birth_rate"`` is ``lambda_s``);
:func:`product_grid` and :func:`magnitude_grid` make Cartesian grids.

Example (the lambda_r x lambda_s sweep of PHD-context Fig. 15)::

    updates = magnitude_grid(np.logspace(-1, 1, 9), np.logspace(-2, 0, 9))
    filt, params = build_tracker(PHDConfig(), seq.info)
    result = sweep(filt, params, jax.random.PRNGKey(0),
                   seq.detections, updates, ground_truth=seq.gt_table,
                   first_frame=seq.first_frame)
    result.scores["MOTA"].reshape(9, 9)   # [clutter rate, birth rate]
"""

from __future__ import annotations

import functools
import itertools
import time
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import multihost_utils
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from jaxtyping import Array, ArrayLike
from tqdm import tqdm

from jaxtrack.association.offline import finalise_tracks, track_rows
from jaxtrack.association.retrodiction import detection_rows, retrodict
from jaxtrack.association.smoothing import smooth_tracks
from jaxtrack.configs import SMOOTHING, TrackerConfig
from jaxtrack.context.intensity import Intensity
from jaxtrack.errors import InputError
from jaxtrack.filters.base import Filter, fit_detections, run, run_batch
from jaxtrack.filters.registry import build_tracker, properties_of, writes_events
from jaxtrack.io import MotSequence, MotTable
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader
from jaxtrack.metrics.evaluate import SUMMARY_KEYS, EvalConfig, evaluate_sequence
from jaxtrack.metrics.events import EventRows
from jaxtrack.parameters import leaf_values, replace_leaves
from jaxtrack.pipelines.frame_context import streamed_params
from jaxtrack.pipelines.stream import (
    STREAM_CHUNK_FRAMES,
    check_frame_tracker,
    rows_output,
    streamed_rows,
)
from jaxtrack.pipelines.tracking import check_tracking_memory, smoothing_noise
from jaxtrack.resources import check_memory
from jaxtrack.types import Detections

#: Parameter names of the magnitudes ``lambda_r`` (clutter) and ``lambda_s`` (birth).
CLUTTER_RATE = "clutter_rate"
BIRTH_RATE = "birth_rate"


class SweepResult(NamedTuple):
    """Outputs of :func:`sweep`, one entry per configuration (batch order).

    Attributes:
        updates: the swept values, ``{name: [batch, ...]}`` (empty when a batched PyTree was
            given instead of updates).
        scores: ``{name: [batch]}`` for every name of
            :data:`~jaxtrack.metrics.evaluate.SUMMARY_KEYS` (empty without ground truth).
        log_likelihood: the PHD measurement log-likelihood summed over frames, ``[batch]``
            (NaN for filters that do not report one).
        rows: the scored output rows of each configuration.
        events: for a tracker that writes events (:func:`sweep_frames` of the hierarchical
            tracker), each configuration's event rows, as ``RES.events.csv`` holds them;
            None otherwise.
        seconds: where :func:`sweep`'s wall time went (None from :func:`sweep_frames`):
            ``trace`` (JAX tracing and lowering the batched program), ``compile`` (XLA),
            ``wait`` (the host waiting for the devices' results: the first call whole, the
            others beyond what scoring the previous chunk overlapped), ``score`` (the host's
            post-processing and scoring, which runs while the devices run the next chunk,
            except for the last one) and ``total`` (from tracing to the last score).
    """

    updates: dict[str, np.ndarray]
    scores: dict[str, np.ndarray]
    log_likelihood: np.ndarray
    rows: list[MotTable]
    events: list[EventRows] | None = None
    seconds: dict[str, float] | None = None


def product_grid(axes: Mapping[str, ArrayLike]) -> dict[str, np.ndarray]:
    """The Cartesian product of per-path values, flattened in C order (first path slowest).

    Args:
        axes: ``{path: values[n_k, ...]}``; the grid has ``prod(n_k)`` configurations.

    Returns:
        ``{path: [prod(n_k), ...]}``, ready for :func:`batch_params` / :func:`sweep`; reshape
        a score to ``[n_1, n_2, ...]`` to get the grid back.

    Raises:
        InputError: no axes, or an axis without values.
    """
    if not axes:
        raise InputError("a grid needs at least one axis")
    values = {path: np.asarray(v) for path, v in axes.items()}
    for path, v in values.items():
        if v.ndim == 0 or v.shape[0] == 0:
            raise InputError(f"grid axis {path!r} needs a non-empty array of values")
    index = list(itertools.product(*(range(v.shape[0]) for v in values.values())))
    columns = np.asarray(index, dtype=np.int64).reshape(len(index), len(values))
    return {path: v[columns[:, k]] for k, (path, v) in enumerate(values.items())}


def log_grid(low: float, high: float, num: int) -> np.ndarray:
    """``num`` values from ``low`` to ``high``, evenly spaced in log, each rounded to 12
    significant digits.

    ``np.logspace`` alone gives 0.20000000000000004 for the middle of ``(0.02, 2, 3)`` on
    some CPUs and 0.2 on others (its power function's last bits differ between vectorised
    code paths); the rounding makes grid values, and a grid point's equality with a default,
    the same on every machine. (No tracker sees the difference: parameters are float32.)
    """
    values = np.logspace(np.log10(low), np.log10(high), num)
    return np.array([float(f"{value:.12g}") for value in values])


def magnitude_grid(clutter_rates: ArrayLike, birth_rates: ArrayLike) -> dict[str, np.ndarray]:
    """The ``lambda_r x lambda_s`` grid of PHD-context Fig. 15 (clutter rate slowest).

    Scales the clutter and birth intensities (PHD-context eq. 19-20); the densities, and
    the first frame's ``initial_intensity`` (``initial_rate``), stay as in the base
    parameters.

    Args:
        clutter_rates: ``lambda_r`` values (false detections per frame), 1-D, > 0.
        birth_rates: ``lambda_s`` values (births per frame), 1-D, > 0.

    Returns:
        Updates for :data:`CLUTTER_RATE` and :data:`BIRTH_RATE`,
        ``len(clutter_rates) * len(birth_rates)`` configurations.

    Raises:
        InputError: rates that are not 1-D, empty, or not positive and finite.
    """
    axes = {CLUTTER_RATE: clutter_rates, BIRTH_RATE: birth_rates}
    for path, rates in axes.items():
        rates = np.asarray(rates, dtype=np.float64)
        if rates.ndim != 1 or rates.size == 0 or not np.all(np.isfinite(rates) & (rates > 0)):
            raise InputError(f"{path} values must be a non-empty 1-D array of positive numbers")
    return product_grid({path: np.asarray(r, np.float32) for path, r in axes.items()})


def batch_params(base_params: Any, updates: Mapping[str, ArrayLike]) -> Any:
    """A batch of parameter PyTrees: ``base_params`` with the named leaves replaced.

    Args:
        base_params: an unbatched parameter PyTree of a registered tracker (e.g.
            :class:`~jaxtrack.filters.phd.PHDParams`); its properties tree
            (:func:`~jaxtrack.filters.registry.properties_of`) resolves the names.
        updates: ``{parameter name: values[batch, *leaf shape]}``, the same ``batch`` for all.

    Returns:
        The PyTree with a leading ``batch`` axis on every leaf (NumPy arrays).

    Raises:
        InputError: no updates, an unknown name, values of the wrong shape, or different
            batch sizes.
    """
    if not updates:
        raise InputError("no parameter updates to sweep")
    values = {name: np.asarray(v) for name, v in updates.items()}
    sizes = {name: (v.shape[0] if v.ndim else None) for name, v in values.items()}
    if len(set(sizes.values())) != 1 or None in sizes.values():
        raise InputError(f"all updates need the same leading batch size, got {sizes}")
    (batch,) = set(sizes.values())
    if batch == 0:
        raise InputError("the batch of configurations is empty")
    host = jax.tree.map(np.asarray, base_params)
    properties = properties_of(base_params)
    leaves = leaf_values(host, properties, tuple(values))
    for name, v in values.items():
        shape = np.shape(leaves[name])
        if v.shape[1:] != shape:
            raise InputError(
                f"{name}: expected values of shape [batch, {', '.join(map(str, shape))}]"
                f" = {(batch, *shape)}, got {v.shape}"
            )
    batched = jax.tree.map(lambda leaf: np.broadcast_to(leaf, (batch, *leaf.shape)), host)
    replaced = replace_leaves(batched, properties, values)
    return jax.tree.map(np.asarray, replaced)


def pad_components(intensity: Intensity, num_components: int) -> Intensity:
    """The same intensity with dead mixture components (weight 0) appended.

    Dead components contribute nothing (:mod:`~jaxtrack.context.intensity`), so parameter
    PyTrees of different numbers of components (e.g. UM and GM) can share one batch and one
    compile.

    Raises:
        InputError: ``num_components`` smaller than the intensity's.
    """
    extra = num_components - intensity.weights.shape[0]
    if extra < 0:
        raise InputError(f"cannot pad {intensity.weights.shape[0]} components to {num_components}")
    dim = intensity.means.shape[-1]
    return intensity._replace(
        weights=jnp.concatenate([intensity.weights, jnp.zeros((extra,), intensity.weights.dtype)]),
        means=jnp.concatenate([intensity.means, jnp.zeros((extra, dim), intensity.means.dtype)]),
        covs=jnp.concatenate(
            [
                intensity.covs,
                jnp.broadcast_to(jnp.eye(dim, dtype=intensity.covs.dtype), (extra, dim, dim)),
            ]
        ),
    )


def common_shapes(params: Sequence[Any]) -> list[Any]:
    """Pads the intensities of several parameter sets to common numbers of components.

    Uniform (UM) and learned intensities, or contexts learned on different data, differ in
    their numbers of mixture components and so in their PyTree shapes; padded with dead
    components (:func:`pad_components`) they track identically, can be stacked into one
    batch, and :func:`~jaxtrack.pipelines.tracking.track_sequences` or :func:`sweep`
    compiles once for all of them.

    Args:
        params: parameter NamedTuples of one type (e.g. ``PHDParams``); every field holding
            an :class:`~jaxtrack.context.intensity.Intensity` is padded.
    """
    fields = [name for name, value in params[0]._asdict().items() if isinstance(value, Intensity)]
    sizes = {name: max(getattr(p, name).weights.shape[0] for p in params) for name in fields}
    return [
        p._replace(**{name: pad_components(getattr(p, name), sizes[name]) for name in fields})
        for p in params
    ]


def sweep(
    filt: Filter,
    params: Any,
    key: Array,
    detections: Detections,
    updates: Mapping[str, ArrayLike] | None = None,
    *,
    ground_truth: MotTable | None = None,
    first_frame: int = 1,
    output: str = "offline",
    max_gap: int = 8,
    retrodiction: int = 0,
    smoothing: str = "none",
    chunk_size: int = 16,
    devices: Sequence[jax.Device] | None = None,
    eval_config: EvalConfig | None = None,
    progress: bool = False,
) -> SweepResult:
    """Runs and scores a filter for a batch of configurations.

    Every configuration ``b`` gives exactly what ``run(filt, keys[b], params_b,
    fit_detections(detections))`` gives (same keys, same frames), post-processed as
    ``jaxtrack track`` does (``"offline"``:
    :func:`~jaxtrack.association.offline.finalise_tracks`; ``"online"``: the filter's
    frame-by-frame output). The detections are first brought to the capacity ``jaxtrack
    track`` gives the sequence (:func:`~jaxtrack.filters.base.fit_detections`), so a
    configuration gives what ``jaxtrack track`` gives with it, unless the sequence has crowded
    frames (which the tracker runs at a capacity of their own).

    Args:
        filt: the filter (its per-frame info must have ``tracks`` and ``candidates``, as
            :func:`~jaxtrack.filters.phd.phd_filter` and the Kalman tracker have).
        params: the base parameter PyTree when ``updates`` is given; otherwise a batched
            PyTree (a leading batch axis on every leaf, e.g. from :func:`batch_params`).
        key: one PRNG key shared by all configurations (common random numbers), or one key
            per configuration (``[batch]`` typed keys or ``[batch, 2]`` raw keys).
        detections: padded detections ``[num_frames, max_detections]``.
        updates: ``{parameter name: values[batch, ...]}`` (see :func:`batch_params`).
        ground_truth: rows of the ground truth (e.g. ``MotSequence.gt_table``); rows outside
            the span are ignored. None: no scores.
        first_frame: 1-based frame number of time index 0.
        output: ``"offline"`` (default, as ``jaxtrack track``) or ``"online"``.
        max_gap: longest gap filled by the offline output.
        retrodiction: the most frames the offline output extends each track backwards onto
            ``detections`` (:func:`~jaxtrack.association.retrodiction.retrodict`; 0: off), as
            ``PHDConfig.retrodiction``.
        smoothing: ``"rts"`` smooths every configuration's offline output
            (:func:`~jaxtrack.association.smoothing.smooth_tracks`, after the retrodiction)
            under its own ``motion_noise_std`` and ``measurement_noise_std`` (the PHD
            tracker's defaults for parameters without them), as the configurations'
            ``smoothing``; ``"none"`` (default): off.
        chunk_size: the most configurations one device runs per compiled call: the batch
            is shared evenly among the fewest groups of at most this size (162
            configurations at 28: six groups of 27), each call runs one group per device
            (three calls of 2 x 27 on two devices), and the last call is padded by
            repeating the last configuration. A configuration's numbers depend on the
            group size, not on the number of devices.
        devices: devices to shard the batch over (default: all, ``jax.devices()``; a
            sweep uses at most one device per group). On CPU,
            :func:`~jaxtrack.pipelines.runtime.use_cpu_cores`
            gives one device per core.
        eval_config: evaluation settings.
        progress: show a progress bar over the chunks.

    Returns:
        The :class:`SweepResult`.

    Raises:
        InputError: bad updates or batch, keys of the wrong shape, a bad chunk size or output,
            a negative ``retrodiction`` or one with the online output, a ``smoothing`` that
            is unknown or used with the online output.
    """
    if output not in ("offline", "online"):
        raise InputError(f"output must be 'offline' or 'online', got {output!r}")
    if chunk_size <= 0:
        raise InputError(f"chunk_size must be positive, got {chunk_size}")
    if max_gap < 0:
        raise InputError(f"max_gap must be >= 0, got {max_gap}")
    if retrodiction < 0:
        raise InputError(f"retrodiction must be >= 0, got {retrodiction}")
    if retrodiction and output == "online":
        raise InputError(
            "retrodiction extends the offline output; the online output would ignore it "
            f"(retrodiction={retrodiction}, output='online')"
        )
    SMOOTHING.check("smoothing", smoothing)
    if smoothing != "none" and output == "online":
        raise InputError(
            f"smoothing re-estimates the offline output; the online output would ignore it "
            f"(smoothing={smoothing!r}, output='online')"
        )
    if updates is None:
        batched = jax.tree.map(np.asarray, params)
        swept = {}
    else:
        batched = batch_params(params, updates)
        swept = {name: np.asarray(v) for name, v in updates.items()}
    batch = _batch_size(batched)
    keys, key_impl = _config_keys(key, batch)
    detections = fit_detections(detections)
    num_frames = detections.mask.shape[0]

    devices = list(jax.devices() if devices is None else devices)
    num_chunks, per_device, num_devices = _chunking(batch, chunk_size, len(devices))
    if jax.process_count() > 1:  # every host takes part in every call
        num_devices = len(devices)
        num_chunks = -(-batch // (per_device * num_devices))
    mesh = Mesh(np.asarray(devices[:num_devices]), ("batch",))
    chunk = per_device * num_devices
    order = np.minimum(np.arange(num_chunks * chunk), batch - 1)
    replicated = NamedSharding(mesh, PartitionSpec())
    device_detections = jax.tree.map(lambda x: _put(x, replicated), detections)
    sharded = NamedSharding(mesh, PartitionSpec("batch"))

    def arguments(c):
        window = order[c * chunk : (c + 1) * chunk]
        chunk_params = jax.tree.map(lambda leaf: _put(leaf[window], sharded), batched)
        return _put(keys[window], sharded), chunk_params, device_detections

    first_arguments = arguments(0)
    seconds = dict.fromkeys(("trace", "compile", "wait", "score"), 0.0)
    start = time.perf_counter()
    lowered = _sweep_function(filt, mesh, key_impl).lower(*first_arguments)
    seconds["trace"] = time.perf_counter() - start
    compiled = lowered.compile()
    seconds["compile"] = time.perf_counter() - start - seconds["trace"]
    _check_sweep_memory(compiled, per_device, devices[:num_devices])

    def dispatch(c):
        return compiled(*(first_arguments if c == 0 else arguments(c)))

    span = (first_frame, first_frame + num_frames - 1)
    detection_table = detection_rows(detections, first_frame) if retrodiction else None
    gt = None if ground_truth is None else ground_truth.frame_span(*span)
    chunks = range(num_chunks)
    if progress:
        chunks = tqdm(chunks, desc="sweep", unit="chunk")
    rows, scores, log_likelihood = [], [], []
    pending = dispatch(0)
    for c in chunks:
        # Fetch this chunk, launch the next, then score this one while the next runs. (Two
        # executions in flight at once can deadlock XLA's CPU client with several forced
        # host devices, so the next chunk starts only once this one is done.)
        waited = time.perf_counter()
        tracks, candidates, chunk_log_likelihood = _gather(pending)
        seconds["wait"] += time.perf_counter() - waited
        if c + 1 < num_chunks:
            pending = dispatch(c + 1)
        scoring = time.perf_counter()
        for b in range(min(chunk, batch - c * chunk)):
            config_tracks = jax.tree.map(lambda x, b=b: x[b], tracks)
            if output == "offline":
                config_candidates = jax.tree.map(lambda x, b=b: x[b], candidates)
                config_rows = finalise_tracks(
                    config_tracks, config_candidates, max_gap, first_frame
                )
                if retrodiction:
                    config_rows = retrodict(config_rows, detection_table, first_frame, retrodiction)
                if smoothing == "rts":
                    config_rows = smooth_tracks(
                        config_rows, *smoothing_noise(batched, c * chunk + b)
                    )
            else:
                config_rows = track_rows(config_tracks, first_frame)
            rows.append(config_rows)
            log_likelihood.append(chunk_log_likelihood[b])
            if gt is not None:
                scores.append(evaluate_sequence(gt, config_rows, span, eval_config).summary())
        seconds["score"] += time.perf_counter() - scoring
    seconds["total"] = time.perf_counter() - start
    return SweepResult(
        updates=swept,
        scores=_score_arrays(scores),
        log_likelihood=np.asarray(log_likelihood),
        rows=rows,
        seconds=seconds,
    )


def sweep_frames(
    seq: MotSequence,
    video: VideoReader,
    config: TrackerConfig,
    updates: Mapping[str, ArrayLike] | None = None,
    *,
    params: Any = None,
    seed: int = 0,
    chunk_size: int = 16,
    chunk_frames: int = STREAM_CHUNK_FRAMES,
    eval_config: EvalConfig | None = None,
    progress: bool = False,
) -> SweepResult:
    """Runs and scores a tracker that looks at the images (CMT, hierarchical, fusion) for a
    batch of configurations, its video decoded once.

    Configuration ``b`` gives what ``jaxtrack track`` gives with it:
    :func:`~jaxtrack.pipelines.stream.track_streamed` ``(seq, video, config, seed,
    params_b, chunk_frames)`` (the same key ``PRNGKey(seed)`` for every configuration, i.e.
    common random numbers; the same chunks and detection capacities; the same result rows,
    identities merged for a tracker that re-associates them), up to float32 rounding of
    the batched program (:func:`~jaxtrack.filters.base.run_batch`). The frames are streamed
    in chunks of ``chunk_frames`` (decoded ahead in a background thread); each chunk runs
    ``chunk_size`` configurations per compiled, vmapped call, so a sweep holds all the
    configurations' states but only a few chunks of images, and compiles once. One device
    (the default one); rows are scored against ``seq.gt_table`` when the sequence has one.

    Args:
        seq: the loaded sequence (or span); its ``seqinfo.ini`` size is the frames' size.
        video: its open frames (:func:`~jaxtrack.io.video.open_sequence_frames`), left open.
        config: the tracker's configuration (its registry entry must use frames).
        updates: ``{parameter name: values[batch, ...]}`` over the base parameters
            (:func:`batch_params`); None: ``params`` is already batched.
        params: the base parameters (default: those ``jaxtrack track`` builds for the
            sequence, :func:`~jaxtrack.pipelines.frame_context.streamed_params`: zones
            learned on the fly, the background image, the fusion context), or, without
            ``updates``, a batched PyTree (e.g. for trackers without named parameters).
        seed: PRNG seed of every configuration.
        chunk_size: configurations per compiled call.
        chunk_frames: frames per compiled call.
        eval_config: evaluation settings.
        progress: a progress bar over the frames.

    Returns:
        The :class:`SweepResult` (``log_likelihood`` NaN: these trackers report none;
        ``events``: the hierarchical tracker's event rows per configuration).

    Raises:
        InputError: a tracker that reads no frames, frames of another size than the
            sequence's, bad updates or batch, a chunk size that is not positive.
        ResourceError: ``chunk_size`` configurations at once would need more memory than
            the machine has.
    """
    check_frame_tracker(seq, video, config, "sweep")
    if chunk_size <= 0 or chunk_frames <= 0:
        raise InputError(
            f"chunk_size and chunk_frames must be positive, got {chunk_size}, {chunk_frames}"
        )
    filt, _ = build_tracker(config, seq.info)
    base = streamed_params(config, seq, video, seed)[0] if params is None else params
    if updates is None:
        batched, swept = jax.tree.map(np.asarray, base), {}
    else:
        batched = batch_params(base, updates)
        swept = {name: np.asarray(v) for name, v in updates.items()}
    batch = _batch_size(batched)
    check_tracking_memory([seq], config, chunk_frames, min(chunk_size, batch))
    keys = jnp.broadcast_to(jax.random.PRNGKey(seed), (batch, 2))
    bar = tqdm(total=seq.num_frames, desc="sweep", unit="frame", disable=not progress)
    with bar, FrameStream(video, seq.first_frame, seq.last_frame, chunk_frames) as frames:
        outputs = run_batch(
            filt,
            keys,
            batched,
            seq.detections,
            chunk_frames=chunk_frames,
            group_size=chunk_size,
            frame_output=rows_output(config),
            frames=frames,
            progress=bar.update,
        )
    span = (seq.first_frame, seq.last_frame)
    gt = seq.gt_table.frame_span(*span) if seq.gt_table is not None else None
    rows, scores, events = [], [], []
    for b in range(batch):
        # a configuration with no rows is a sweep's answer, not a mistake: no warning
        made = streamed_rows(jax.tree.map(lambda x, b=b: x[b], outputs), seq, config, warn=False)
        rows.append(made.rows)
        events.append(made.events)
        if gt is not None:
            scores.append(evaluate_sequence(gt, made.rows, span, eval_config).summary())
    return SweepResult(
        updates=swept,
        scores=_score_arrays(scores),
        log_likelihood=np.full(batch, np.nan),
        rows=rows,
        events=events if writes_events(config) else None,
    )


@functools.lru_cache(maxsize=8)
def _sweep_function(filt: Filter, mesh: Mesh, key_impl: str | None):
    """``jit(shard_map(vmap(run)))`` over the ``batch`` axis of ``mesh`` (cached per filter).

    ``shard_map`` gives every device its own slice of configurations to run independently:
    no cross-device communication at all. (Sharding a plain ``jit(vmap(run))`` instead lets
    the partitioner turn the batched predicates of the filter's while loops into
    cross-device all-reduces inside the loops, which is slow and can deadlock XLA's CPU
    client with forced host devices.) Keys arrive as raw key data; ``key_impl`` names the
    implementation of typed keys (None for raw keys).
    """

    def one(key, params, detections):
        if key_impl is not None:
            key = jax.random.wrap_key_data(key, impl=key_impl)
        _, info = run(filt, key, params, detections)
        log_likelihood = getattr(info, "log_likelihood", None)
        total = jnp.nan if log_likelihood is None else jnp.sum(log_likelihood)
        return info.tracks, info.candidates, total

    batch = PartitionSpec("batch")
    return jax.jit(
        jax.shard_map(
            jax.vmap(one, in_axes=(0, 0, None)),
            mesh=mesh,
            in_specs=(batch, batch, PartitionSpec()),
            out_specs=batch,
            # The filter's scans start from unsharded initial states; nothing here
            # communicates across devices, so the varying-axis type check is not needed.
            check_vma=False,
        )
    )


def _check_sweep_memory(compiled: Any, per_device: int, devices: Sequence[jax.Device]) -> None:
    """Refuses a sweep whose calls would need more host memory than the machine has.

    The compiled call's own estimate (XLA's ``memory_analysis``: the temporaries, inputs and
    outputs of one device's program) times the CPU devices, which share the host's memory
    (accelerators report their own out-of-memory errors).
    """
    cpus = sum(device.platform == "cpu" for device in devices)
    analysis = compiled.memory_analysis() if cpus else None
    if analysis is None:
        return
    per_call = cpus * (
        analysis.temp_size_in_bytes
        + analysis.argument_size_in_bytes
        + analysis.output_size_in_bytes
        - analysis.alias_size_in_bytes
    )
    check_memory(
        per_call,
        f"a sweep call of {per_device} configurations on each of {cpus} CPU devices",
        "a smaller chunk_size or fewer CPU devices (JAX_NUM_CPU_DEVICES=N)",
    )


def _chunking(batch: int, chunk_size: int, num_devices: int) -> tuple[int, int, int]:
    """``(number of calls, configurations per device per call, devices used)``.

    The batch is cut into the fewest even groups of at most ``chunk_size`` configurations
    (the least padding: 162 configurations at 28 are six groups of 27, not five of 28 and a
    sixth padded by six) and each call runs one group per device, on at most as many devices
    as there are groups. A device's program therefore always runs the same number of
    configurations whatever the number of devices, so a configuration's numbers do not
    depend on how many devices run the sweep (XLA's batched float32 arithmetic may round
    differently for another batch size)."""
    groups = -(-batch // chunk_size)
    per_device = -(-batch // groups)
    devices = min(num_devices, groups)
    return -(-batch // (per_device * devices)), per_device, devices


def _score_arrays(scores: list[dict[str, float]]) -> dict[str, np.ndarray]:
    """Per-configuration summaries as ``{name: [batch]}`` (empty without scores)."""
    if not scores:
        return {}
    return {name: np.asarray([s[name] for s in scores]) for name in SUMMARY_KEYS}


def _put(value: np.ndarray, sharding: NamedSharding) -> jax.Array:
    """A global array from host data present on every process (one or several hosts)."""
    value = np.asarray(value)
    return jax.make_array_from_callback(value.shape, sharding, lambda index: value[index])


def _gather(outputs):
    """Device outputs as host NumPy arrays (all-gathered across processes when several)."""
    if jax.process_count() > 1:
        return multihost_utils.process_allgather(outputs, tiled=True)
    return jax.tree.map(np.asarray, outputs)


def _batch_size(batched: Any) -> int:
    leaves = jax.tree.leaves(batched)
    sizes = {leaf.shape[0] if leaf.ndim else None for leaf in leaves}
    if not leaves or len(sizes) != 1 or None in sizes or 0 in sizes:
        raise InputError(
            "a batched parameter PyTree needs the same non-zero leading batch size on every "
            f"leaf, got sizes {sorted(sizes, key=str)}"
        )
    return sizes.pop()


def _config_keys(key: Array, batch: int) -> tuple[np.ndarray, str | None]:
    """One key per configuration as raw key data ``[batch, 2]``, and the typed keys' impl."""
    impl = None
    if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key):
        impl = str(jax.random.key_impl(key))
        key = jax.random.key_data(key)
    data = np.asarray(key)
    if data.ndim == 1:
        return np.broadcast_to(data, (batch, *data.shape)).copy(), impl
    if data.ndim != 2 or data.shape[0] != batch:
        raise InputError(
            f"key must be one key or one per configuration ({batch}), got key data of shape "
            f"{data.shape}"
        )
    return data, impl
