"""CMT's compiled step (jaxtrack.filters.cmt) on scenes with known truth.

Oracles: drawn scenes whose boxes are known exactly (targets as two-tone rectangles over a
grey background, detections = the true boxes), hand-built zone and overlap cases, and
a loop over parameter sets for the vmapped sweep.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxtrack.context.zones import SceneZones
from jaxtrack.filters.base import run
from jaxtrack.filters.cmt_tracker import CMTConfig, build_cmt
from jaxtrack.types import Detections, FrameInputs, SequenceInfo

SIZE = (160, 120)  # width, height
SMALL = {"max_components": 4, "particles_per_component": 24}
INFO = SequenceInfo("drawn", 30, SIZE[0], SIZE[1], 25.0)


def two_tone(image: np.ndarray, box, top, bottom) -> None:
    """Draws a target: the top half of its box in ``top``, the bottom half in ``bottom``."""
    x, y, w, h = (round(v) for v in box)
    image[y : y + h // 2, x : x + w] = top
    image[y + h // 2 : y + h, x : x + w] = bottom


def scene(boxes_per_frame, colours, scores=None, num_slots=4):
    """Frames and padded detections of targets drawn at ``boxes_per_frame[t][k]``."""
    frames = []
    for boxes in boxes_per_frame:
        image = np.full((SIZE[1], SIZE[0], 3), 128, np.uint8)
        for box, (top, bottom) in zip(boxes, colours, strict=False):
            two_tone(image, box, top, bottom)
        frames.append(image)
    return frame_inputs(frames, boxes_per_frame, scores, num_slots)


def frame_inputs(frames, boxes_per_frame, scores=None, num_slots=4) -> FrameInputs:
    """The frames with ``boxes_per_frame[t]`` as frame ``t``'s detections, padded to
    ``num_slots`` (score 0.99, or ``scores`` ``[T, num_slots]``, on the real ones)."""
    det_boxes, det_mask = [], []
    for boxes in boxes_per_frame:
        padded = np.tile([0.0, 0.0, 1.0, 1.0], (num_slots, 1))
        padded[: len(boxes)] = np.reshape(boxes, (-1, 4))
        det_boxes.append(padded)
        det_mask.append(np.arange(num_slots) < len(boxes))
    mask = np.array(det_mask)
    given = np.where(mask, 0.99 if scores is None else scores, 0.0)
    detections = Detections(
        jnp.asarray(np.array(det_boxes), jnp.float32),
        jnp.asarray(given, jnp.float32),
        jnp.asarray(mask),
    )
    return FrameInputs(detections, jnp.asarray(np.array(frames)))


def walkers(num_frames=20):
    """Two targets walking apart horizontally, one above the other."""
    return [
        [(20.0 + 2 * t, 20.0, 16.0, 36.0), (120.0 - 2 * t, 70.0, 16.0, 36.0)]
        for t in range(num_frames)
    ]


COLOURS = [((200, 30, 30), (30, 30, 200)), ((30, 200, 30), (200, 200, 30))]


@pytest.mark.parametrize("variant", ["mtb", "cpd", "cmt"])
def test_tracks_two_walkers_with_persistent_identities(variant):
    truth = walkers()
    inputs = scene(truth, COLOURS)
    filt, params = build_cmt(CMTConfig(variant=variant, **SMALL), INFO)
    _, info = jax.jit(lambda k, p, i: run(filt, k, p, i))(jax.random.PRNGKey(0), params, inputs)
    mask = np.asarray(info.tracks.mask)
    assert mask.sum(axis=1)[2:].tolist() == [2] * (len(truth) - 2)
    boxes, ids = np.asarray(info.tracks.boxes), np.asarray(info.tracks.ids)
    errors = []
    for t in range(2, len(truth)):
        for k, true_box in enumerate(truth[t]):
            shown = np.flatnonzero(mask[t])
            slot = shown[np.argmin(np.abs(boxes[t, shown, 1] - true_box[1]))]
            errors.append(boxes[t, slot] - true_box)
            assert ids[t, slot] == k  # the first blob of frame 0 started id 0
    # The likelihood's noise is 2.4-5.4 px on these boxes (SDV, 16 x 36): estimates from 24
    # particles scatter by about that.
    errors = np.abs(np.array(errors))
    assert np.sqrt(np.mean(errors**2)) < 2.5 and errors.max() < 6.0


def test_a_blob_far_from_every_zone_enters_only_without_the_contextual_proposal():
    # Frame 0: one target; from frame 5 a second one appears mid-image, far from the zone.
    truth = [walkers()[t][:1] if t < 5 else walkers()[t] for t in range(12)]
    inputs = scene(truth, COLOURS)
    zones = SceneZones(np.array([[0.0, 0.0, 10.0, 10.0]]), None, None)
    counts = {}
    for variant in ("mtb", "cpd"):
        filt, params = build_cmt(CMTConfig(variant=variant, **SMALL), INFO, zones)
        params = params._replace(enter_distance=jnp.float32(1.0))  # default: no gate
        _, info = run(filt, jax.random.PRNGKey(1), params, inputs)
        counts[variant] = int(np.asarray(info.candidates.mask)[-1].sum())
    assert counts == {"mtb": 2, "cpd": 1}


def test_a_second_blob_on_one_target_starts_no_lasting_duplicate():
    # Each frame has the target's box and a slightly shifted copy (IoU ~ 0.6).
    truth = [[box, (box[0] + 3, box[1] + 3, box[2], box[3])] for box, _ in walkers(12)]
    inputs = scene(truth, [COLOURS[0], COLOURS[0]])
    filt, params = build_cmt(CMTConfig(variant="mtb", **SMALL), INFO)
    _, info = run(filt, jax.random.PRNGKey(2), params, inputs)
    assert np.asarray(info.tracks.mask)[3:].sum(axis=1).max() == 1


def test_output_waits_for_a_confident_blob():
    truth = [walkers()[t][:1] for t in range(10)]
    scores = np.array([[0.5] * 4 if t < 6 else [0.99] * 4 for t in range(10)])
    inputs = scene(truth, COLOURS[:1], scores=scores)
    filt, params = build_cmt(CMTConfig(variant="cmt", **SMALL), INFO)
    _, info = run(filt, jax.random.PRNGKey(3), params, inputs)
    shown = np.asarray(info.tracks.mask).sum(axis=1)
    candidates = np.asarray(info.candidates.mask).sum(axis=1)
    assert shown[:6].tolist() == [0] * 6 and shown[6:].tolist() == [1] * 4
    assert candidates[1:].tolist() == [1] * 9


def test_vmapped_parameter_sets_equal_separate_runs():
    inputs = scene(walkers(8), COLOURS)
    filt, params = build_cmt(CMTConfig(variant="cmt", **SMALL), INFO)
    stds = jnp.array([[0.05, 0.02, 0.05, 0.05], [0.1, 0.05, 0.1, 0.1]], jnp.float32)
    batched = jax.tree.map(lambda leaf: jnp.stack([leaf, leaf]), params)
    batched = batched._replace(mixture=batched.mixture._replace(motion_noise_std=stds))

    def boxes(p):
        return run(filt, jax.random.PRNGKey(4), p, inputs)[1].tracks.boxes

    together = jax.jit(jax.vmap(boxes))(batched)
    for k in range(2):
        alone = jax.tree.map(lambda leaf, k=k: leaf[k], batched)
        np.testing.assert_allclose(together[k], jax.jit(boxes)(alone), atol=1e-3)


def test_gradient_of_the_likelihood_support_wrt_noise_is_finite():
    inputs = scene(walkers(6), COLOURS)
    filt, params = build_cmt(CMTConfig(variant="cmt", **SMALL), INFO)

    def support(std):
        p = params._replace(mixture=params.mixture._replace(motion_noise_std=std))
        _, info = run(filt, jax.random.PRNGKey(5), p, inputs)
        return jnp.sum(jnp.where(info.alive, info.log_support, 0.0))

    grad = jax.grad(support)(params.mixture.motion_noise_std)
    assert np.all(np.isfinite(np.asarray(grad))) and np.any(np.asarray(grad) != 0)
