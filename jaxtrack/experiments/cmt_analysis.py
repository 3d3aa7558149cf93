"""CMT's two analyses (Cui et al., Sec. VII-C, Fig. 8 and Fig. 9), as numbers per frame.

**Fig. 8, prediction precision of the proposal.** The paper sums, over every proposed
particle, the distance from its position ``(P_x, P_y)`` to the annotated target position, and
compares the contextual proposal (CPD) with the Gaussian (constant-velocity transition)
prior. :func:`proposal_distances` sums, per component that tracks a ground-truth target, its
proposed particles' distances to that target's centre, and averages these sums over the
tracked targets of the frame (so that more tracked targets do not mean a larger number). A
component tracks the target whose centre is nearest to where the component is (its
*anchor*), when within :data:`MATCH_GATE` of the target's box height; other components (false
tracks) are left out. Two comparisons (:func:`prediction_analysis`):

* *same particles* (:func:`one_step_proposals`): on every frame ``t``, the particles of one
  run (MTb+CPD's, after frame ``t``'s resampling, ``CMTState``) are proposed onto frame
  ``t + 1`` by both proposals, with the same key: only the proposal differs. Anchor: the
  particles' mean moved by their mean velocity (the prior's expected position).
* *tracker runs* (:func:`tracker_particles`): MTb and MTb+CPD each run on the span (same seed
  and blobs) and each frame's proposed particles (``CMTInfo.particles``, before reweighting)
  are scored; the runs' components differ, so this mixes the proposal with what it did to
  the tracks. Anchor: the proposed particles' mean.

**Fig. 9, discriminative power of the observation model.** Two nearby, similarly dressed
targets A and B (the scripted *crossing* of a synthetic video scene,
:mod:`jaxtrack.datasets.video_script`): A's appearance model is learned online from its
ground-truth boxes with B as its field of context (B's model learned alongside), and on each
frame, before the frame's update, :func:`~jaxtrack.filters.cmt_observation.likelihood_gap`
gives ``log p(z_A | m_A) - log p(z_B | m_A)`` (eq. 11) with the contextual weights (COM,
eqs. 13-17) and with equal weights (EWOM). A negative gap is a frame on which A's model
prefers B: a potential swap.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from jaxtrack.configs import TrackerConfig
from jaxtrack.context.zones import SceneZones
from jaxtrack.datasets.video_files import TRUTH_FILE
from jaxtrack.errors import InputError
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt import CMTParams
from jaxtrack.filters.cmt_observation import (
    NUM_LEVELS,
    STEP,
    box_features,
    init_appearance,
    likelihood_gap,
    num_features,
    observation_weights,
    update_appearance,
)
from jaxtrack.filters.cmt_proposal import contextual_proposal
from jaxtrack.filters.cmt_tracker import CMTConfig, cmt_params
from jaxtrack.filters.mixture_models import bootstrap_proposal
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import MotSequence, load_sequence
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader, open_sequence_frames
from jaxtrack.models.dynamics import POSITION, VELOCITY
from jaxtrack.pipelines.stream import STREAM_CHUNK_FRAMES
from jaxtrack.types import Detections, MotTable

#: A component tracks a target when its anchor lies within this many of the target's box
#: heights of the target's centre (:func:`proposal_distances`).
MATCH_GATE = 0.5

#: Fig. 8's span of PETS09-S2L1 (the paper used a subsequence of PETS2004).
FIG8_FRAMES = (1, 100)
#: Fig. 8's labels of the two proposals.
PRIOR = "Gaussian prior (MTb)"
CONTEXTUAL = "contextual proposal (CPD)"
#: Fig. 9 starts this many frames before the crossing's first frame.
FIG9_LEAD = 40
#: Frames of Fig. 9 in quick runs.
QUICK_FIG9_FRAMES = 12


class FrameParticles(NamedTuple):
    """What :func:`tracker_particles` keeps of each frame ``t``.

    Attributes:
        proposed: the positions of the particles proposed on frame ``t``
            (``CMTInfo.particles``) ``[T, K, N, 2]``.
        proposed_alive: the slots alive while frame ``t`` was proposed ``[T, K]``.
        posterior: the particles after frame ``t``'s resampling (the next proposal's input)
            ``[T, K, N, 6]``.
        estimates: the local decisions after frame ``t`` ``[T, K, 6]``.
        alive: the slots alive after frame ``t`` ``[T, K]``.
    """

    proposed: np.ndarray
    proposed_alive: np.ndarray
    posterior: np.ndarray
    estimates: np.ndarray
    alive: np.ndarray


def _particles_output(state: Any, info: Any, index: Any) -> FrameParticles:
    """The per-frame output of :func:`tracker_particles` (``frame_output`` of ``run``)."""
    del index
    return FrameParticles(
        info.particles[..., POSITION],
        info.alive,
        state.mixture.particles,
        state.estimates,
        state.mixture.alive,
    )


def tracker_particles(
    loaded: MotSequence,
    reader: VideoReader,
    config: TrackerConfig,
    seed: int,
    zones: SceneZones | None,
) -> FrameParticles:
    """CMT's particles on every frame of a sequence span (:class:`FrameParticles`), run as
    :func:`~jaxtrack.pipelines.stream.track_streamed` runs it (same key, chunks and
    detection capacities)."""
    filt, params = build_tracker(config, loaded.info, zones)
    with FrameStream(reader, loaded.first_frame, loaded.last_frame, STREAM_CHUNK_FRAMES) as frames:
        _, output = run(
            filt,
            jax.random.PRNGKey(seed),
            params,
            loaded.detections,
            chunk_frames=STREAM_CHUNK_FRAMES,
            fit_capacity=True,
            frame_output=_particles_output,
            frames=frames,
        )
    return FrameParticles(*(np.asarray(leaf) for leaf in output))


@jax.jit
def one_step_proposals(
    key: Array, particles: FrameParticles, params: CMTParams, blobs: Detections
) -> tuple[Array, Array]:
    """Both proposals from the same particles: frame ``t``'s posterior proposed onto frame
    ``t + 1``'s blobs by the Gaussian prior (the constant-velocity transition,
    :func:`~jaxtrack.filters.mixture_models.bootstrap_proposal`) and by the contextual
    proposal (:func:`~jaxtrack.filters.cmt_proposal.contextual_proposal`, CMT eq. 5), one
    key per frame shared by both.

    Args:
        key: PRNG key.
        particles: :func:`tracker_particles` of frames ``0..T-2`` (posterior, estimates,
            alive are read).
        params: the tracker's parameters.
        blobs: the detections of frames ``1..T-1``.

    Returns:
        The proposed positions ``[T-1, K, N, 2]`` of the prior and of the contextual proposal.
    """
    keys = jax.random.split(key, blobs.mask.shape[0])

    def frame(key_t, posterior, estimates, alive, blobs_t):
        prior, _ = bootstrap_proposal(key_t, posterior, params.mixture, blobs_t)
        draw = contextual_proposal(
            key_t,
            posterior,
            estimates,
            alive,
            params.proposal,
            params.mixture.motion_noise_std,
            blobs_t,
            params.zone_boxes,
            params.zone_mask,
        )
        return prior[..., POSITION], draw.particles[..., POSITION]

    return jax.vmap(frame)(keys, particles.posterior, particles.estimates, particles.alive, blobs)


def proposal_distances(
    positions: np.ndarray,
    anchors: np.ndarray,
    alive: np.ndarray,
    gt_boxes: np.ndarray,
    gt_mask: np.ndarray,
    gate: float = MATCH_GATE,
) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 8's prediction error per frame (module docstring).

    Args:
        positions: proposed particle positions ``[T, K, N, 2]`` (pixels).
        anchors: where each component is taken to be when it is matched to a target
            ``[T, K, 2]`` (e.g. its particles' mean).
        alive: ``[T, K]`` slots holding a component.
        gt_boxes: ground-truth boxes ``(x, y, w, h)`` ``[T, G, 4]``.
        gt_mask: ``[T, G]`` real ground-truth slots.
        gate: a component tracks the target whose centre is nearest to its anchor, when
            within ``gate`` box heights of it.

    Returns:
        Per frame, the mean over the tracking components of the summed distance of their
        particles to their target's centre (NaN on a frame with none), and the number of
        tracking components ``[T]``.
    """
    centres = gt_boxes[..., :2] + gt_boxes[..., 2:] / 2
    gap = np.linalg.norm(anchors[:, :, None, :] - centres[:, None, :, :], axis=-1)
    gap = np.where(gt_mask[:, None, :], gap, np.inf)
    target = np.argmin(gap, axis=-1)
    nearest = np.take_along_axis(gap, target[..., None], -1)[..., 0]
    heights = np.take_along_axis(gt_boxes[..., 3], target, -1)
    tracking = alive & (nearest <= gate * heights)
    own = np.take_along_axis(centres, target[..., None], 1)
    sums = np.linalg.norm(positions - own[:, :, None, :], axis=-1).sum(axis=-1)
    count = tracking.sum(axis=1)
    total = np.where(tracking, sums, 0.0).sum(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan), count


class LikelihoodGaps(NamedTuple):
    """Fig. 9's numbers.

    Attributes:
        frames: the 1-based frames scored (from the pair's second shared frame).
        com: ``log p(z_A | m_A) - log p(z_B | m_A)`` with COM's weights, per frame.
        ewom: the same with equal weights.
        ids: the ground-truth ids of A and B.
    """

    frames: np.ndarray
    com: np.ndarray
    ewom: np.ndarray
    ids: tuple[int, int]


def pair_boxes(
    gt: MotTable, ids: tuple[int, int], first: int, last: int
) -> tuple[np.ndarray, np.ndarray]:
    """The frames in ``first..last`` where both targets have a box, and their boxes
    ``[T, 2, 4]`` (A first)."""
    by_id = [
        {int(f): box for f, box in zip(gt.frames[gt.ids == i], gt.boxes[gt.ids == i], strict=True)}
        for i in ids
    ]
    frames = np.array(sorted(f for f in by_id[0] if f in by_id[1] and first <= f <= last))
    boxes = np.array([[by_id[0][f], by_id[1][f]] for f in frames], np.float32).reshape(-1, 2, 4)
    return frames, boxes


def likelihood_gaps(
    reader: VideoReader, frames: np.ndarray, boxes: np.ndarray, ids: tuple[int, int]
) -> LikelihoodGaps:
    """Fig. 9 on a pair of targets (module docstring), with CMT's default observation
    parameters and its field-of-context radius (``d_thr`` box heights, :func:`cmt_params`).

    Args:
        reader: the sequence's frames.
        frames: 1-based frames where both targets are annotated (:func:`pair_boxes`), at
            least two.
        boxes: their ground-truth boxes ``[T, 2, 4]``, A first.
        ids: the targets' ids (for the record).

    Returns:
        The gaps from the second frame on (the first initialises the models).
    """
    params = cmt_params(CMTConfig())
    state = init_appearance(2, num_features(STEP))
    com, ewom = [], []
    for index, frame_number in enumerate(frames):
        image = jnp.asarray(reader.read(int(frame_number)))
        state, gaps = _gap_step(
            state,
            image,
            jnp.asarray(boxes[index]),
            index == 0,
            NUM_LEVELS,
            params.observation,
            params.proposal.context_distance,
        )
        if index > 0:
            com.append(float(gaps[0]))
            ewom.append(float(gaps[1]))
    return LikelihoodGaps(np.asarray(frames[1:]), np.asarray(com), np.asarray(ewom), ids)


@functools.partial(jax.jit, static_argnums=4)
def _gap_step(state, image, boxes, first, num_levels, params, context_distance):
    """One frame of :func:`likelihood_gaps`: the COM and EWOM gaps of A under the models
    learned so far, then the models updated with the frame's boxes."""
    features = jax.vmap(box_features, (None, 0))(image, boxes)
    positions = boxes[:, :2] + boxes[:, 2:] / 2
    alive = jnp.ones(2, bool)
    radius = context_distance * boxes[:, 3]
    gaps = []
    for contextual in (True, False):
        weights = observation_weights(
            state.counts, positions, alive, radius, params, num_levels, contextual
        )
        gaps.append(likelihood_gap(features, features[::-1], state, weights, params)[0])
    born = jnp.full(2, first)
    state = update_appearance(state, features, alive, ~alive, born, params)
    return state, jnp.stack(gaps)


def prediction_analysis(
    folder: Path,
    video: Path | None,
    frames: tuple[int, int],
    prior: TrackerConfig,
    contextual: TrackerConfig,
    seed: int,
    zones: SceneZones | None,
    zone_note: str,
) -> dict[str, Any]:
    """Fig. 8 (module docstring) on a sequence span, as JSON-ready numbers.

    Args:
        folder: the MOTChallenge folder (with ground truth).
        video: its frames when the folder has none, else None.
        frames: the 1-based inclusive span.
        prior: CMT's configuration with the Gaussian prior (``variant="mtb"``).
        contextual: the same with the contextual proposal (``variant="cpd"``).
        seed: the runs' seed.
        zones: the entry/exit zones of the sequence (e.g. those ``jaxtrack track`` learns
            on the whole sequence, :func:`~jaxtrack.pipelines.zones.tracker_zones`).
        zone_note: what the zones are, in words (for the record).
    """
    loaded = load_sequence(folder, frames)
    gt_boxes, gt_mask = np.asarray(loaded.ground_truth.boxes), np.asarray(loaded.ground_truth.mask)
    runs = {}
    for label, config in {PRIOR: prior, CONTEXTUAL: contextual}.items():
        with open_sequence_frames(folder, loaded.info, video) as reader:
            runs[label] = tracker_particles(loaded, reader, config, seed, zones)
    tracker_runs = {
        label: proposal_distances(
            run.proposed, run.proposed.mean(axis=2), run.proposed_alive, gt_boxes, gt_mask
        )[0]
        for label, run in runs.items()
    }
    # the same particles (the MTb+CPD run's posterior on frame t) proposed onto frame t + 1
    source = runs[CONTEXTUAL]
    _, params = build_tracker(contextual, loaded.info, zones)
    previous = FrameParticles(*(leaf[:-1] for leaf in source))
    blobs = jax.tree.map(lambda x: x[1:], loaded.detections)
    drawn = one_step_proposals(jax.random.PRNGKey(seed), previous, params, blobs)
    posterior = previous.posterior
    anchors = (posterior[..., POSITION] + posterior[..., VELOCITY]).mean(axis=2)
    same_particles = {
        label: proposal_distances(
            np.asarray(positions), anchors, previous.alive, gt_boxes[1:], gt_mask[1:]
        )[0]
        for label, positions in zip((PRIOR, CONTEXTUAL), drawn, strict=True)
    }
    return {
        "sequence": loaded.info.name,
        "frames": list(range(loaded.first_frame, loaded.last_frame + 1)),
        "zones": zone_note,
        "same_particles": _comparison(same_particles, 1),
        "tracker_runs": _comparison(tracker_runs, 0),
    }


def _comparison(distances: dict[str, np.ndarray], offset: int) -> dict[str, Any]:
    """The two proposals' distances, per frame (``None`` before ``offset`` and where a run
    tracks no target) and summarised over the frames where both track one."""
    both = np.all([np.isfinite(d) for d in distances.values()], axis=0)
    prior, cpd = distances[PRIOR], distances[CONTEXTUAL]
    return {
        "distances": {k: [None] * offset + _json_floats(v) for k, v in distances.items()},
        "mean": {k: _json_float(np.mean(v[both])) for k, v in distances.items()},
        "cpd_below_prior_fraction": _json_float(np.mean(cpd[both] < prior[both])),
        "frames_compared": int(both.sum()),
    }


def scene_crossings(folder: Path) -> list[tuple[tuple[int, ...], tuple[int, int]]]:
    """``(people's gt ids, (first, last))`` of every scripted crossing of a synthetic video
    scene's folder (its truth file), in the script's order.

    Raises:
        InputError: a folder without a truth file.
    """
    path = Path(folder) / TRUTH_FILE
    if not path.is_file():
        raise InputError(f"{path}: no truth file (is it a `jaxtrack simulate --video` scene?)")
    events = json.loads(path.read_text())["events"]
    return [
        (tuple(event["ids"]), tuple(event["frames"]))
        for event in events
        if event["type"] == "crossing"
    ]


def discrimination_analysis(folder: Path, quick: bool = False) -> dict[str, Any]:
    """Fig. 9 (module docstring) on the scripted crossing of a synthetic video scene's folder
    (``jaxtrack simulate --video``: its two similarly dressed people), from
    :data:`FIG9_LEAD` frames before it to its end (quick: its last :data:`QUICK_FIG9_FRAMES`
    frames), as JSON-ready numbers."""
    crossings = scene_crossings(folder)
    if not crossings:
        raise InputError(f"{folder}: the scene scripts no crossing")
    ids, crossing_frames = crossings[0]
    first, last = crossing_frames
    first = last - QUICK_FIG9_FRAMES if quick else first - FIG9_LEAD
    loaded = load_sequence(folder)
    frames, boxes = pair_boxes(loaded.gt_table, ids, first, last)
    with open_sequence_frames(folder, loaded.info) as reader:
        gaps = likelihood_gaps(reader, frames, boxes, ids)
    return {
        "sequence": loaded.info.name,
        "ids": list(ids),
        "crossing_frames": list(crossing_frames),
        "frames": gaps.frames.tolist(),
        "COM": _json_floats(gaps.com),
        "EWOM": _json_floats(gaps.ewom),
        "mean": {"COM": _json_float(gaps.com.mean()), "EWOM": _json_float(gaps.ewom.mean())},
        "com_above_ewom_fraction": _json_float(np.mean(gaps.com > gaps.ewom)),
        "negative_frames": {"COM": int(np.sum(gaps.com < 0)), "EWOM": int(np.sum(gaps.ewom < 0))},
    }


def _json_float(value: float) -> float | None:
    """A float for JSON (NaN as None)."""
    return None if not np.isfinite(value) else round(float(value), 4)


def _json_floats(values: np.ndarray) -> list[float | None]:
    return [_json_float(value) for value in values]
