"""CMT's two analyses (Cui et al., Sec. VII-C, Fig. 8 and Fig. 9), as numbers per frame.

**Fig. 8, prediction precision of the proposal.** The paper sums, over every proposed
particle, the distance from its position ``(P_x, P_y)`` to the annotated target position, and
compares the contextual proposal (CPD) with the Gaussian (constant-velocity transition)
prior. Here CMT runs twice on the same span, as MTb (the prior) and as MTb+CPD (the
contextual proposal), with the same seed and blobs; each frame's *proposed* particles are
read from the tracker's per-frame info (``CMTInfo.particles``, before reweighting and
resampling) and :func:`proposal_distances` sums, per component that tracks a ground-truth
target, its particles' distances to that target's centre, and averages these sums over the
tracked targets of the frame (so that a run that tracks more targets is not penalised). A
component tracks the target whose centre is nearest to its particles' mean, when that is
within :data:`MATCH_GATE` of the target's box height; other components (false tracks) are
left out.

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

import json
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxtrack.configs import TrackerConfig
from jaxtrack.context.zones import SceneZones
from jaxtrack.datasets.video_files import TRUTH_FILE
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt import FEATURE_STEP, NUM_LEVELS, num_features
from jaxtrack.filters.cmt_observation import (
    box_features,
    init_appearance,
    likelihood_gap,
    observation_weights,
    update_appearance,
)
from jaxtrack.filters.cmt_tracker import CMTConfig, cmt_params
from jaxtrack.filters.registry import build_tracker
from jaxtrack.io import MotSequence, load_sequence
from jaxtrack.io.frame_stream import FrameStream
from jaxtrack.io.video import VideoReader, open_sequence_frames
from jaxtrack.models.dynamics import POSITION
from jaxtrack.pipelines.stream import STREAM_CHUNK_FRAMES
from jaxtrack.types import MotTable

#: A component tracks a target when its particles' mean lies within this many of the
#: target's box heights of the target's centre.
MATCH_GATE = 0.5


class ProposedParticles(NamedTuple):
    """What :func:`proposed_particles` keeps of each frame: the proposed positions and the
    living slots."""

    positions: np.ndarray
    alive: np.ndarray


def _proposal_output(state: Any, info: Any, index: Any) -> ProposedParticles:
    """The per-frame output of :func:`proposed_particles` (``frame_output`` of ``run``)."""
    del state, index
    return ProposedParticles(info.particles[..., POSITION], info.alive)


def proposed_particles(
    loaded: MotSequence,
    reader: VideoReader,
    config: TrackerConfig,
    seed: int,
    zones: SceneZones | None,
) -> ProposedParticles:
    """CMT's proposed particle positions ``[T, K, N, 2]`` and living slots ``[T, K]`` on every
    frame of a sequence span, run as :func:`~jaxtrack.pipelines.stream.track_streamed`
    runs it (same key, chunks and detection capacities)."""
    filt, params = build_tracker(config, loaded.info, zones)
    with FrameStream(reader, loaded.first_frame, loaded.last_frame, STREAM_CHUNK_FRAMES) as frames:
        _, output = run(
            filt,
            jax.random.PRNGKey(seed),
            params,
            loaded.detections,
            chunk_frames=STREAM_CHUNK_FRAMES,
            fit_capacity=True,
            frame_output=_proposal_output,
            frames=frames,
        )
    return ProposedParticles(np.asarray(output.positions), np.asarray(output.alive))


def proposal_distances(
    positions: np.ndarray,
    alive: np.ndarray,
    gt_boxes: np.ndarray,
    gt_mask: np.ndarray,
    gate: float = MATCH_GATE,
) -> tuple[np.ndarray, np.ndarray]:
    """Fig. 8's prediction error per frame (module docstring).

    Args:
        positions: proposed particle positions ``[T, K, N, 2]`` (pixels).
        alive: ``[T, K]`` slots holding a component.
        gt_boxes: ground-truth boxes ``(x, y, w, h)`` ``[T, G, 4]``.
        gt_mask: ``[T, G]`` real ground-truth slots.
        gate: a component tracks a target within ``gate`` box heights of its centre.

    Returns:
        Per frame, the mean over the tracking components of the summed distance of their
        particles to their target's centre (NaN on a frame with none), and the number of
        tracking components ``[T]``.
    """
    centres = gt_boxes[..., :2] + gt_boxes[..., 2:] / 2
    means = positions.mean(axis=2)
    gap = np.linalg.norm(means[:, :, None, :] - centres[:, None, :, :], axis=-1)
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


def pair_boxes(gt: MotTable, ids: tuple[int, int], first: int, last: int):
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
    step = jax.jit(_gap_step, static_argnums=4)
    state = init_appearance(2, num_features(FEATURE_STEP))
    com, ewom = [], []
    for index, frame_number in enumerate(frames):
        image = jnp.asarray(reader.read(int(frame_number)))
        state, gaps = step(
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


#: Fig. 8's span of PETS09-S2L1 (the paper used a subsequence of PETS2004).
FIG8_FRAMES = (1, 100)
#: Fig. 9 starts this many frames before the crossing's first frame.
FIG9_LEAD = 40
#: Frames of Fig. 9 in quick runs.
QUICK_FIG9_FRAMES = 12


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
    distances, counts = {}, {}
    labels = {"Gaussian prior (MTb)": prior, "contextual proposal (CPD)": contextual}
    for label, config in labels.items():
        with open_sequence_frames(folder, loaded.info, video) as reader:
            proposed = proposed_particles(loaded, reader, config, seed, zones)
        gt = loaded.ground_truth
        distances[label], counts[label] = proposal_distances(
            proposed.positions, proposed.alive, np.asarray(gt.boxes), np.asarray(gt.mask)
        )
    both = np.all([np.isfinite(d) for d in distances.values()], axis=0)
    prior, cpd = distances.values()
    return {
        "sequence": loaded.info.name,
        "frames": list(range(loaded.first_frame, loaded.last_frame + 1)),
        "zones": zone_note,
        "distances": {k: _json_floats(v) for k, v in distances.items()},
        "tracked_targets": {k: v.tolist() for k, v in counts.items()},
        "mean": {k: _json_float(np.nanmean(v[both])) for k, v in distances.items()},
        "cpd_below_prior_fraction": _json_float(np.mean(cpd[both] < prior[both])),
        "frames_compared": int(both.sum()),
    }


def discrimination_analysis(folder: Path, quick: bool = False) -> dict[str, Any]:
    """Fig. 9 (module docstring) on the scripted crossing of a synthetic video scene's folder
    (``jaxtrack simulate --video``: its two similarly dressed people), from
    :data:`FIG9_LEAD` frames before it to its end (quick: its last :data:`QUICK_FIG9_FRAMES`
    frames), as JSON-ready numbers."""
    truth = json.loads((folder / TRUTH_FILE).read_text())
    crossing = next(event for event in truth["events"] if event["type"] == "crossing")
    ids = tuple(crossing["ids"])
    first, last = crossing["frames"]
    first = last - QUICK_FIG9_FRAMES if quick else first - FIG9_LEAD
    loaded = load_sequence(folder)
    frames, boxes = pair_boxes(loaded.gt_table, ids, first, last)
    with open_sequence_frames(folder, loaded.info) as reader:
        gaps = likelihood_gaps(reader, frames, boxes, ids)
    return {
        "sequence": loaded.info.name,
        "ids": list(ids),
        "crossing_frames": crossing["frames"],
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
