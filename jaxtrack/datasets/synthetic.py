"""Seeded synthetic surveillance scenes with known birth and clutter context.

The generator draws a MOTChallenge-style sequence (ground truth + detections) from the
generative model assumed by the PHD-context filter (SPEC section 1), so that learned birth and
clutter intensities can be compared with the true ones returned alongside. Everything is set
by a :class:`~jaxtrack.datasets.scene_config.SceneConfig`; a seed fixes the sequence (NumPy
``default_rng`` on the host).

**State** ``x = (y1, vy1, y2, vy2, w, h)``: box centre (column, row), centre velocity in
pixels/frame, box width and height. The ground-truth box of a target is its state's box.

**Perspective.** The nominal size at row ``y2`` is linear in the row, as for upright objects
on a flat ground plane seen by a level pinhole camera:
``h_nom(y2) = a (y2 - r0)``, ``w_nom(y2) = rho h_nom(y2)`` (``a = height_per_row``,
``r0 = horizon_row``, ``rho = aspect_ratio``).

**Births.** Each frame ``Poisson(lambda_s)`` targets are born (``lambda_s = birth_rate``),
each in zone ``z`` with probability proportional to its weight, with state
``x ~ N(mu_z, Sigma_z)`` (:func:`zone_birth_gaussian`): centre and velocity from the zone,
``E[w, h | y2] = (w_nom(y2), h_nom(y2))`` and a relative spread ``size_spread`` of the
target's own size. The true birth intensity is therefore exactly the Gaussian mixture
``gamma(x) = lambda_s sum_z pi_z N(x; mu_z, Sigma_z)`` (:func:`birth_intensity`); a birth whose
box would stick out of the image is shifted inside (rare with the default zones).

Zones beyond that model (:class:`~jaxtrack.datasets.scene_config.EntryZone`): an ``extent``
adds to the centre an offset uniform over a rectangle (an image edge, a gateway), with the
size following the row it lands on (:func:`zone_extent_factor`); ``height_scale`` and
``aspect_ratio`` give the zone's targets their own object class, whose nominal size
``(rho_z h_z, h_z)``, ``h_z = s_z h_nom(y2)``, they keep for life; a zone with
``active_frames`` adds its births ``lambda_s pi_z`` only in those frames. For such scenes the
written true birth intensity is the sequence's average, moment-matched: one Gaussian per zone
with the rectangle's variance ``e^2 / 3`` added, weighted by ``pi_z`` times the share of the
frames ``1..T`` in which the zone is open.

**Dynamics** (per frame, ``T = 1``). Centre and velocity follow SPEC's SDV constant-velocity
model exactly: ``y1 += vy1 + w_{k-1} n1 / 2``, ``vy1 += w_{k-1} n1``, ``n1 ~ N(0,
sigma_n1^2)``, and likewise ``(y2, vy2)`` with ``h_{k-1}`` and ``n2``. The size follows the
perspective law times the target's own scale: with ``u = log(h / h_nom(y2))`` and
``u_bar`` its value at birth,
``u_k = u_bar + phi (u_{k-1} - u_bar) + nh``, ``nh ~ N(0, sigma_nh^2)``,
``h_k = h_nom(y2_k) exp(u_k)`` (same for ``w``). For ``phi = 1`` and a fixed row this is
SPEC's SDV size noise ``h_k ~= h_{k-1} (1 + nh)`` in log form; the perspective term makes boxes
grow as targets come down the image. A target leaves the scene when its box no longer lies
fully inside the image, or, older than ``min_exit_age`` frames, when its centre enters an exit
zone (within ``exit_radius`` standard deviations of the zone centre).

**Detections.** A target is *occluded* when a target nearer the camera (larger box bottom
row) covers more than ``occlusion_threshold`` of its box area; it is detected with
probability ``detection_prob`` (``occluded_detection_prob`` when occluded). A detection of box
``(cx, cy, w, h)`` is ``N((cx, cy, w, h), diag(s_w w, s_h h, s_w w, s_h h)^2)`` (SPEC
likelihood), unless it is *badly placed* (probability ``misplaced_detection_prob``, default
0): then it is one of :func:`badly_placed_boxes`' boxes (a part of the person, a shifted box,
a box spilling over a neighbour), which overlaps the target by IoU 0.18-0.5, so that the
IoU-0.5 evaluation counts it as a false positive although the target produced it. With
probability ``extra_detection_prob`` (default 0) a detected target also yields a second,
badly placed box. Both are the target's detections (``det_target_ids``), not clutter; they
take the true detections' scores. Clutter is Poisson per frame: each source ``s`` emits
``Poisson(r_s)`` boxes ``N(m_s, S_s)`` in ``(cx, cy, w, h)`` (spatially persistent clutter,
e.g. waving vegetation), and ``Poisson(r_u)`` boxes are uniform over the image and the size
range. The true clutter intensity is
``kappa(z) = lambda_r [pi_u / V + (1 - pi_u) sum_s pi_s N(z; m_s, S_s)]`` with
``lambda_r = r_u + sum_s r_s``, ``pi_u = r_u / lambda_r``, ``pi_s = r_s / sum r_s``
(:func:`clutter_intensity`). A source with an ``extent`` shifts its box centres uniformly over
a rectangle; a flickering source (``off_frames > 0``) emits only in its on frames, a two-state
Markov chain started from its stationary law (:attr:`SyntheticScene.clutter_source_on`);
then ``r_s`` above is the source's mean rate ``rate * duty_cycle`` and its Gaussian is
moment-matched (the written true intensity is the average over frames). Scores are
``Beta(target_score)`` for true detections and ``Beta(clutter_score)`` for clutter, in
``(0, 1]``.

Written boxes are rounded to 1/1000 pixel; detection boxes are clipped to the image (which
alters a few clutter boxes near the border relative to the intensity they were drawn from).
Detections are shuffled within each frame, so their order carries no information.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxtrack.boxes import cxcywh_to_xywh
from jaxtrack.context.intensity import Intensity
from jaxtrack.context.io import save_context
from jaxtrack.datasets.scene_config import EntryZone, SceneConfig, config_to_dict
from jaxtrack.errors import InputError
from jaxtrack.io.motchallenge import (
    MotTable,
    SequenceInfo,
    pad_detections,
    pad_ground_truth,
    write_mot_file,
    write_seqinfo,
)
from jaxtrack.types import Detections, GroundTruth

#: Smallest box side a generated box can have before clipping, pixels.
MIN_BOX_SIDE = 2.0
#: Most targets in view at once (burn-in included). Pedestrian scenes have at most a few
#: hundred people in view; the limit keeps the per-frame occlusion test (every pair of
#: targets) at 10^6 pairs and the ground truth at ``MAX_TARGETS`` rows per frame, and a scene
#: above it is refused (``InputError`` naming ``birth_rate``) before its births are drawn.
MAX_TARGETS = 1000
#: Box pairs per block of :func:`occluded_fraction` (2 MB per float64 pair array).
OCCLUSION_PAIRS_PER_BLOCK = 1 << 18
#: Decimals kept in written boxes (pixels) and scores.
BOX_DECIMALS = 3
SCORE_DECIMALS = 4


@dataclasses.dataclass(frozen=True)
class SyntheticScene:
    """A generated sequence with its truth.

    Row-aligned arrays follow the rows of ``det_table`` (``det_*``) or ``gt_table``
    (``gt_*``); per-frame arrays have one entry per frame ``1..T`` (index ``t`` = frame
    ``t + 1``).

    Attributes:
        seed: the seed it was generated from.
        config: the configuration.
        info: sequence information (``seqinfo.ini``).
        det_table: detections (true and clutter), sorted by frame, shuffled within a frame.
        gt_table: ground truth, ids from 1, conf 1, sorted by frame then id.
        detections: padded detections, ``[num_frames, max_detections]``.
        ground_truth: padded ground truth, ``[num_frames, max_objects]``.
        birth_intensity: the true birth intensity ``gamma(x)`` (6-D state space).
        clutter_intensity: the true clutter intensity ``kappa(z)`` (4-D ``(cx, cy, w, h)``).
        det_target_ids: ground-truth id a detection comes from; -1 for clutter.
        det_clutter_source: -1 for a true detection, ``s`` for clutter source ``s``
            (index into ``config.clutter_sources``), ``len(clutter_sources)`` for uniform
            clutter.
        gt_states: true state ``(y1, vy1, y2, vy2, w, h)`` of each ground-truth row.
        gt_occluded: whether the target was occluded in that frame.
        gt_detected: whether the target was detected in that frame.
        birth_frames: frame of each birth in ``1..T`` (targets present at frame 1 that were
            born during the burn-in are not births of the sequence).
        birth_ids: ground-truth id of each birth.
        birth_zones: index into ``config.zones`` of each birth.
        birth_states: state of each birth (its first ground-truth state).
        num_targets: live targets per frame.
        num_births: births per frame.
        num_target_detections: detections produced by targets per frame (badly placed
            ones included).
        num_clutter: clutter detections per frame and source, ``[num_frames,
            num_sources + 1]``; the last column counts uniform clutter.
        clutter_source_on: whether each clutter source was on, ``[num_frames, num_sources]``
            (always True for a source that does not flicker).
    """

    seed: int
    config: SceneConfig
    info: SequenceInfo
    det_table: MotTable
    gt_table: MotTable
    detections: Detections
    ground_truth: GroundTruth
    birth_intensity: Intensity
    clutter_intensity: Intensity
    det_target_ids: np.ndarray
    det_clutter_source: np.ndarray
    gt_states: np.ndarray
    gt_occluded: np.ndarray
    gt_detected: np.ndarray
    birth_frames: np.ndarray
    birth_ids: np.ndarray
    birth_zones: np.ndarray
    birth_states: np.ndarray
    num_targets: np.ndarray
    num_births: np.ndarray
    num_target_detections: np.ndarray
    num_clutter: np.ndarray
    clutter_source_on: np.ndarray

    @property
    def is_clutter(self) -> np.ndarray:
        """True for the rows of ``det_table`` that are false detections."""
        return self.det_clutter_source >= 0

    def summary(self) -> dict[str, float | int | dict[str, float]]:
        """Measured statistics of the scene (for reports and the CLI).

        Returns:
            Target counts per frame (min/mean/max), births per frame, clutter per frame (in
            total and per source, ``"uniform"`` for the uniform part), detection rates
            (overall, unoccluded, occluded) and the occluded share of target-frames.
        """
        occluded = self.gt_occluded
        detected = self.gt_detected
        names = [source.name for source in self.config.clutter_sources] + ["uniform"]
        per_source = self.num_clutter.mean(axis=0) if len(self.num_clutter) else []
        return {
            "frames": int(self.info.seq_length),
            "targets": int(np.unique(self.gt_table.ids).size),
            "targets_per_frame_min": int(self.num_targets.min()),
            "targets_per_frame_mean": float(self.num_targets.mean()),
            "targets_per_frame_max": int(self.num_targets.max()),
            "births": int(self.num_births.sum()),
            "births_per_frame": float(self.num_births.mean()),
            "clutter_per_frame": float(self.num_clutter.sum(axis=1).mean()),
            "clutter_per_frame_by_source": {
                name: float(rate) for name, rate in zip(names, per_source, strict=True)
            },
            "detection_rate": _rate(detected),
            "detection_rate_unoccluded": _rate(detected[~occluded]),
            "detection_rate_occluded": _rate(detected[occluded]),
            "occluded_share": _rate(occluded),
        }


def nominal_size(rows, config: SceneConfig, height_scale=1.0, aspect_ratio=None) -> np.ndarray:
    """Perspective law: nominal ``(w, h)`` of a box centred on each row.

    ``h_nom(y2) = a (y2 - r0) s``, ``w_nom = rho h_nom`` (may be <= 0 above the horizon), with
    an object class's height scale ``s`` (1 for the scene's own class).

    Args:
        rows: box-centre rows ``y2``, any shape.
        config: the scene configuration.
        height_scale: ``s``, a number or an array broadcasting with ``rows``.
        aspect_ratio: ``rho``, likewise; None: the scene's ``aspect_ratio``.

    Returns:
        ``[..., 2]`` nominal widths and heights.
    """
    height = config.height_per_row * (np.asarray(rows, np.float64) - config.horizon_row)
    height = height * height_scale
    aspect = config.aspect_ratio if aspect_ratio is None else aspect_ratio
    return np.stack([aspect * height, height], axis=-1)


def zone_aspect_ratio(zone: EntryZone, config: SceneConfig) -> float:
    """The width / height of a zone's object class (the scene's unless the zone sets one)."""
    return config.aspect_ratio if zone.aspect_ratio is None else zone.aspect_ratio


def zone_birth_gaussian(zone: EntryZone, config: SceneConfig) -> tuple[np.ndarray, np.ndarray]:
    """Mean and factor ``L`` of a zone's birth Gaussian, ``x = mean + L e``, ``e ~ N(0, I6)``.

    With the zone centre ``(c1, c2)``, position std ``(s1, s2)``, velocity ``(v1, v2)`` and
    velocity std ``(t1, t2)``, size spread ``q`` and correlation ``c``:
    ``y1 = c1 + s1 e1``, ``vy1 = v1 + t1 e2``, ``y2 = c2 + s2 e3``, ``vy2 = v2 + t2 e4``,
    ``h = h_nom(c2) + a s2 e3 + q h_nom(c2) e6``,
    ``w = w_nom(c2) + rho a s2 e3 + q w_nom(c2) (sqrt(1 - c^2) e5 + c e6)``,
    so ``E[w, h | y2] = (w_nom(y2), h_nom(y2))``; the covariance is ``L L^T``. For a zone of
    another object class, ``a`` is scaled by its ``height_scale`` and ``rho`` is its aspect
    ratio (:func:`nominal_size`). A zone's ``extent`` is added separately
    (:func:`zone_extent_factor`).

    Args:
        zone: the entry zone.
        config: the scene configuration (perspective law and size spread).

    Returns:
        ``mean [6]`` and ``factor [6, 6]`` (lower triangular).
    """
    (c1, c2), (s1, s2) = zone.centre, zone.position_std
    (v1, v2), (t1, t2) = zone.velocity, zone.velocity_std
    aspect = zone_aspect_ratio(zone, config)
    w0, h0 = nominal_size(c2, config, zone.height_scale, aspect)
    slope = config.height_per_row * zone.height_scale
    q, c = config.size_spread, config.size_correlation
    mean = np.array([c1, v1, c2, v2, w0, h0])
    factor = np.zeros((6, 6))
    factor[0, 0], factor[1, 1], factor[2, 2], factor[3, 3] = s1, t1, s2, t2
    factor[4, 2] = aspect * slope * s2
    factor[4, 4] = q * w0 * np.sqrt(1 - c**2)
    factor[4, 5] = q * w0 * c
    factor[5, 2] = slope * s2
    factor[5, 5] = q * h0
    return mean, factor


def zone_extent_factor(zone: EntryZone, config: SceneConfig) -> np.ndarray:
    """``B`` of a zone's uniform offset: a birth's state is shifted by ``B u``, ``u ~ U[-1, 1]^2``.

    With the zone's extent ``(e1, e2)``: ``y1 += e1 u1``, ``y2 += e2 u2`` and the size follows
    the row, ``h += a s e2 u2``, ``w += rho a s e2 u2`` (class height scale ``s``, aspect
    ``rho``), so that ``E[w, h | y2]`` stays the class's nominal size. The offset's covariance
    is ``B B^T / 3``.

    Args:
        zone: the entry zone.
        config: the scene configuration.

    Returns:
        ``[6, 2]`` (zero for a zone without extent).
    """
    e1, e2 = zone.extent
    slope = config.height_per_row * zone.height_scale
    factor = np.zeros((6, 2))
    factor[0, 0] = e1
    factor[2, 1] = e2
    factor[4, 1] = zone_aspect_ratio(zone, config) * slope * e2
    factor[5, 1] = slope * e2
    return factor


def zone_active_shares(config: SceneConfig) -> np.ndarray:
    """The share of the frames ``1..T`` in which each zone gives births (1: always open).

    Args:
        config: the scene configuration.

    Returns:
        ``[num_zones]`` fractions in ``[0, 1]``.
    """
    shares = []
    for zone in config.zones:
        if zone.active_frames is None:
            shares.append(1.0)
            continue
        first, last = max(zone.active_frames[0], 1), min(zone.active_frames[1], config.num_frames)
        shares.append(max(last - first + 1, 0) / config.num_frames)
    return np.array(shares, np.float64)


def birth_intensity(config: SceneConfig) -> Intensity:
    """The true birth intensity ``gamma(x) = lambda_s sum_z pi_z N(x; mu_z, Sigma_z)``.

    No uniform share (``uniform_weight = 0``): every birth enters through a zone. A zone with
    an extent adds ``B B^T / 3`` to its covariance (:func:`zone_extent_factor`; the Gaussian
    then only matches the zone's mean and covariance), and a zone open in a share ``f_z`` of
    the frames counts with ``pi_z f_z`` (the magnitude is the sequence's mean births per
    frame, the weights are renormalised). The volume
    ``[lower, upper]`` (for comparisons with a uniform model) spans the image, velocities in
    ``[-velocity_bound, velocity_bound]`` and sizes in ``[min_box_size, max_box_size]``.

    Args:
        config: the scene configuration.

    Returns:
        The intensity over the 6-D state ``(y1, vy1, y2, vy2, w, h)``.
    """
    vb = config.velocity_bound
    (w_min, h_min), (w_max, h_max) = config.min_box_size, config.max_box_size
    lower = [0.0, -vb, 0.0, -vb, w_min, h_min]
    upper = [config.image_width, vb, config.image_height, vb, w_max, h_max]
    if not config.zones:
        means, covs, weights = np.zeros((1, 6)), np.eye(6)[None], np.zeros(1)
    else:
        gaussians = [zone_birth_gaussian(zone, config) for zone in config.zones]
        means = np.stack([mean for mean, _ in gaussians])
        covs = np.stack([factor @ factor.T for _, factor in gaussians])
        for index, zone in enumerate(config.zones):
            if any(zone.extent):
                extent = zone_extent_factor(zone, config)
                covs[index] += extent @ extent.T / 3
        weights = _zone_probabilities(config)
    shares = zone_active_shares(config)
    magnitude = config.birth_rate
    if np.any(shares < 1):
        rates = weights * shares
        magnitude = config.birth_rate * rates.sum()
        weights = rates / rates.sum() if rates.sum() > 0 else weights
    return _intensity(magnitude, 0.0, lower, upper, weights, means, covs)


def clutter_intensity(config: SceneConfig) -> Intensity:
    """The true clutter intensity: uniform share + one Gaussian per clutter source.

    ``kappa(z) = lambda_r [pi_u / V + (1 - pi_u) sum_s pi_s N(z; m_s, S_s)]`` with
    ``lambda_r = r_u + sum_s r_s``, ``pi_u = r_u / lambda_r``, ``pi_s = r_s / sum_s r_s``,
    ``V`` = image area times the size range. ``r_s`` is a source's mean rate (``rate``
    times its duty cycle), and a source with an extent ``e`` adds ``e^2 / 3`` to its centre
    variances (moment matching: the average over frames of a flickering, patch-shaped source).

    Args:
        config: the scene configuration.

    Returns:
        The intensity over the 4-D measurement ``(cx, cy, w, h)``; ``magnitude`` is the
        expected number of false detections per frame.
    """
    (w_min, h_min), (w_max, h_max) = config.min_box_size, config.max_box_size
    lower = [0.0, 0.0, w_min, h_min]
    upper = [config.image_width, config.image_height, w_max, h_max]
    sources = config.clutter_sources
    total = config.mean_clutter_rate
    source_total = sum(source.mean_rate for source in sources)
    if source_total > 0:
        weights = np.array([source.mean_rate / source_total for source in sources])
        means = np.array([[*source.centre, *source.size] for source in sources])
        stds = np.array([[*source.position_std, *source.size_std] for source in sources])
        variances = stds**2
        extents = np.array([source.extent for source in sources])
        if np.any(extents):
            variances[:, :2] += extents**2 / 3
        covs = np.stack([np.diag(variance) for variance in variances])
        uniform_weight = config.uniform_clutter_rate / total
    else:
        weights, means, covs = np.zeros(1), np.zeros((1, 4)), np.eye(4)[None]
        uniform_weight = 1.0
    return _intensity(total, uniform_weight, lower, upper, weights, means, covs)


def generate_scene(seed: int, config: SceneConfig | None = None) -> SyntheticScene:
    """Generates a synthetic sequence (see the module docstring for the model).

    Args:
        seed: non-negative integer; the same seed and config give identical output.
        config: the scene configuration; default ``SceneConfig()`` (800 frames, about ten
            targets in view).

    Returns:
        The scene with its tables, padded PyTrees, true intensities and per-row truth.
    """
    config = config or SceneConfig()
    rng = np.random.default_rng(seed)
    simulator = _Simulator(config, rng)
    for frame in range(1 - config.burn_in_frames, config.num_frames + 1):
        simulator.step(frame)
    return simulator.scene(seed)


def write_scene(scene: SyntheticScene, out_dir: str | Path) -> Path:
    """Writes a scene as a MOTChallenge folder with its true context.

    Files: ``seqinfo.ini``, ``det/det.txt``, ``gt/gt.txt`` and ``context_truth.npz`` (true
    intensities and metadata, see :mod:`jaxtrack.datasets.context_truth`). ``jaxtrack
    simulate`` adds ``preview.png`` (:func:`jaxtrack.plot.scene.save_scene_preview`).

    Args:
        scene: the generated scene.
        out_dir: the sequence folder (created if needed; these files are overwritten).

    Returns:
        The folder as a :class:`~pathlib.Path`.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_seqinfo(out / "seqinfo.ini", scene.info)
    write_mot_file(out / "det" / "det.txt", scene.det_table)
    write_mot_file(out / "gt" / "gt.txt", scene.gt_table)
    save_context(
        out / "context_truth.npz",
        scene.birth_intensity,
        scene.clutter_intensity,
        _metadata(scene),
    )
    return out


#: Kinds of :func:`badly_placed_boxes`: a part of the person (top or bottom), a box shifted
#: sideways, a box spilling over a neighbour or a shadow.
BADLY_PLACED_KINDS = ("part", "shifted", "spilling")


def badly_placed_boxes(rng: np.random.Generator, boxes: np.ndarray) -> np.ndarray:
    """Badly placed detections of target boxes, as real detectors produce them.

    Each box ``(cx, cy, w, h)`` gets one of :data:`BADLY_PLACED_KINDS`, equally likely:

    * ``part``: the top or the bottom ``f h`` of the box, ``f ~ U(0.3, 0.5)`` (IoU ``f``);
    * ``shifted``: the same box moved sideways by ``d w``, ``d ~ U(0.35, 0.7)``
      (IoU ``(1 - d) / (1 + d)`` in ``[0.18, 0.48]``);
    * ``spilling``: a box ``a w`` wide and ``b h`` high, ``a ~ U(1.8, 2.4)``,
      ``b ~ U(1.0, 1.2)``, that keeps the target at one side (IoU ``1 / (a b)`` in
      ``[0.35, 0.56]``).

    Args:
        rng: the scene's generator.
        boxes: ``[n, 4]`` true ``(cx, cy, w, h)``.

    Returns:
        ``[n, 4]`` badly placed ``(cx, cy, w, h)``.
    """
    n = boxes.shape[0]
    out = np.array(boxes, np.float64, copy=True)
    if n == 0:
        return out
    kind = rng.integers(0, len(BADLY_PLACED_KINDS), n)
    side = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    fraction = rng.uniform(0.3, 0.5, n)
    shift = rng.uniform(0.35, 0.7, n)
    wide, high = rng.uniform(1.8, 2.4, n), rng.uniform(1.0, 1.2, n)
    cx, cy, w, h = boxes.T
    part, shifted, spilling = kind == 0, kind == 1, kind == 2
    out[part, 1] = cy[part] + side[part] * (1 - fraction[part]) * h[part] / 2
    out[part, 3] = fraction[part] * h[part]
    out[shifted, 0] = cx[shifted] + side[shifted] * shift[shifted] * w[shifted]
    out[spilling, 0] = cx[spilling] + side[spilling] * (wide[spilling] - 1) * w[spilling] / 2
    out[spilling, 2] = wide[spilling] * w[spilling]
    out[spilling, 3] = high[spilling] * h[spilling]
    return out


def occluded_fraction(boxes: np.ndarray) -> np.ndarray:
    """Largest share of each box's area covered by one box nearer the camera.

    A box is nearer when its bottom row ``y + h`` is larger (the camera looks down on a
    ground plane). Every pair of boxes is compared, in blocks of boxes so that the
    ``[block, n]`` pair arrays hold about :data:`OCCLUSION_PAIRS_PER_BLOCK` pairs (each box's
    value comes from one block, so blocking does not change it).

    Args:
        boxes: ``(x, y, w, h)`` boxes, ``[n, 4]``.

    Returns:
        ``[n]`` fractions in ``[0, 1]``.
    """
    num_boxes = boxes.shape[0]
    block = max(1, OCCLUSION_PAIRS_PER_BLOCK // max(num_boxes, 1))
    parts = [
        _covered_fraction(boxes[start : start + block], boxes)
        for start in range(0, num_boxes, block)
    ]
    return np.concatenate(parts) if parts else np.zeros(0)


def _covered_fraction(rows: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """:func:`occluded_fraction` of the boxes ``rows`` among all the ``boxes``."""
    x1, y1 = boxes[:, 0], boxes[:, 1]
    x2, y2 = x1 + boxes[:, 2], y1 + boxes[:, 3]
    row_x1, row_y1 = rows[:, 0], rows[:, 1]
    row_x2, row_y2 = row_x1 + rows[:, 2], row_y1 + rows[:, 3]
    width = np.minimum(row_x2[:, None], x2[None]) - np.maximum(row_x1[:, None], x1[None])
    height = np.minimum(row_y2[:, None], y2[None]) - np.maximum(row_y1[:, None], y1[None])
    overlap = np.clip(width, 0, None) * np.clip(height, 0, None)
    nearer = y2[None, :] > row_y2[:, None]
    area = rows[:, 2] * rows[:, 3]
    covered = np.where(nearer, overlap, 0.0) / area[:, None]
    return covered.max(axis=1, initial=0.0)


class _Simulator:
    """Frame-by-frame simulation state (host NumPy); :meth:`scene` assembles the result."""

    def __init__(self, config: SceneConfig, rng: np.random.Generator):
        self.config = config
        self.rng = rng
        zones = config.zones
        gaussians = [zone_birth_gaussian(zone, config) for zone in zones]
        self.zone_means = np.array([m for m, _ in gaussians]).reshape(-1, 6)
        self.zone_factors = np.array([f for _, f in gaussians]).reshape(-1, 6, 6)
        self.zone_extents = np.array([zone_extent_factor(z, config) for z in zones]).reshape(
            -1, 6, 2
        )
        self.zones_have_extent = any(any(zone.extent) for zone in zones)
        self.zone_height_scales = np.array([zone.height_scale for zone in zones])
        self.zone_aspect_ratios = np.array([zone_aspect_ratio(zone, config) for zone in zones])
        self.zones_always_open = all(zone.active_frames is None for zone in zones)
        self.zone_probs = _zone_probabilities(config)
        exits = [zone for zone in zones if zone.exit]
        self.exit_centres = np.array([zone.centre for zone in exits]).reshape(-1, 2)
        self.exit_stds = np.array([zone.position_std for zone in exits]).reshape(-1, 2)
        self.exit_extents = np.array([zone.extent for zone in exits]).reshape(-1, 2)
        sources = config.clutter_sources
        self.source_rates = np.array([source.rate for source in sources])
        self.source_means = np.array([[*s.centre, *s.size] for s in sources]).reshape(-1, 4)
        self.source_stds = np.array([[*s.position_std, *s.size_std] for s in sources]).reshape(
            -1, 4
        )
        self.source_extents = np.array([source.extent for source in sources]).reshape(-1, 2)
        self.sources_have_extent = bool(np.any(self.source_extents))
        # Flicker: per-frame probabilities of switching off (when on) and on (when off).
        self.sources_flicker = any(source.off_frames > 0 for source in sources)
        self.source_duty = np.array([source.duty_cycle for source in sources])
        self.source_switch_off = np.array(
            [1 / s.on_frames if s.off_frames > 0 else 0.0 for s in sources]
        )
        self.source_switch_on = np.array(
            [1 / s.off_frames if s.off_frames > 0 else 1.0 for s in sources]
        )
        self.source_on = np.ones(len(sources), bool)
        # Live targets.
        self.state = np.zeros((0, 6))
        self.log_scale = np.zeros((0, 2))
        self.own_log_scale = np.zeros((0, 2))
        self.height_scale = np.zeros(0)
        self.aspect_ratio = np.zeros(0)
        self.age = np.zeros(0, np.int64)
        self.gt_id = np.zeros(0, np.int64)
        self.next_id = 1
        # Output rows, one list entry per frame.
        self.gt_rows: list[tuple] = []
        self.det_rows: list[tuple] = []
        self.births: list[tuple] = []
        num_frames = config.num_frames
        self.num_targets = np.zeros(num_frames, np.int64)
        self.num_births = np.zeros(num_frames, np.int64)
        self.num_target_detections = np.zeros(num_frames, np.int64)
        self.num_clutter = np.zeros((num_frames, len(sources) + 1), np.int64)
        self.clutter_source_on = np.ones((num_frames, len(sources)), bool)

    def step(self, frame: int) -> None:
        """Propagates survivors, removes leavers, adds births; records frames ``>= 1``."""
        if self.state.shape[0]:
            self._propagate()
            self._remove(self._leaving())
        new_zones = self._birth(frame)
        if frame >= 1:
            self._record(frame, new_zones)

    def _propagate(self) -> None:
        config, rng, state = self.config, self.rng, self.state
        n = state.shape[0]
        sigma_1, sigma_2 = config.motion_noise
        n1 = rng.normal(0.0, sigma_1, n) * state[:, 4]
        n2 = rng.normal(0.0, sigma_2, n) * state[:, 5]
        state[:, 0] += state[:, 1] + n1 / 2
        state[:, 1] += n1
        state[:, 2] += state[:, 3] + n2 / 2
        state[:, 3] += n2
        phi = config.size_reversion
        size_noise = rng.normal(0.0, 1.0, (n, 2)) * np.asarray(config.size_noise)
        self.log_scale = self.own_log_scale + phi * (self.log_scale - self.own_log_scale)
        self.log_scale += size_noise
        nominal = np.maximum(self._nominal(state[:, 2]), MIN_BOX_SIDE)
        state[:, 4:6] = nominal * np.exp(self.log_scale)
        self.age += 1

    def _nominal(self, rows: np.ndarray) -> np.ndarray:
        """Nominal ``(w, h)`` of the live targets (each of its own class) at ``rows``."""
        return nominal_size(rows, self.config, self.height_scale, self.aspect_ratio)

    def _leaving(self) -> np.ndarray:
        config, state = self.config, self.state
        boxes = cxcywh_to_xywh(state[:, [0, 2, 4, 5]])
        outside = (
            (boxes[:, 0] < 0)
            | (boxes[:, 1] < 0)
            | (boxes[:, 0] + boxes[:, 2] > config.image_width)
            | (boxes[:, 1] + boxes[:, 3] > config.image_height)
        )
        beyond_horizon = self._nominal(state[:, 2])[:, 1] < MIN_BOX_SIDE
        offset = np.abs(state[:, None, [0, 2]] - self.exit_centres[None])
        distance = np.maximum(offset - self.exit_extents[None], 0.0) / self.exit_stds[None]
        in_exit = np.any(np.sum(distance**2, axis=-1) <= config.exit_radius**2, axis=1)
        exiting = in_exit & (self.age >= config.min_exit_age)
        return outside | beyond_horizon | exiting

    def _remove(self, leaving: np.ndarray) -> None:
        keep = ~leaving
        self.state = self.state[keep]
        self.log_scale = self.log_scale[keep]
        self.own_log_scale = self.own_log_scale[keep]
        self.height_scale = self.height_scale[keep]
        self.aspect_ratio = self.aspect_ratio[keep]
        self.age = self.age[keep]
        self.gt_id = self.gt_id[keep]

    def _birth(self, frame: int) -> np.ndarray:
        config, rng = self.config, self.rng
        probs, rate = self.zone_probs, config.birth_rate
        if not self.zones_always_open:
            open_probs = probs * np.array([zone.is_active(frame) for zone in config.zones])
            rate = config.birth_rate * open_probs.sum()
            probs = open_probs / max(open_probs.sum(), np.finfo(np.float64).tiny)
        count = rng.poisson(rate) if config.zones else 0
        if count == 0:
            return np.zeros(0, np.int64)
        if self.state.shape[0] + count > MAX_TARGETS:
            raise InputError(
                f"scene config: {self.state.shape[0] + count} targets in view at frame {frame} "
                f"(frames up to 0 are burn-in), above the limit of {MAX_TARGETS} simultaneous "
                f"targets; lower birth_rate (now {config.birth_rate:g})"
            )
        zones = rng.choice(len(config.zones), size=count, p=probs)
        latent = rng.normal(size=(count, 6))
        states = self.zone_means[zones] + np.einsum("nij,nj->ni", self.zone_factors[zones], latent)
        if self.zones_have_extent:
            offsets = rng.uniform(-1.0, 1.0, size=(count, 2))
            states += np.einsum("nij,nj->ni", self.zone_extents[zones], offsets)
        states[:, 4:6] = np.maximum(states[:, 4:6], MIN_BOX_SIDE)
        half_w, half_h = states[:, 4] / 2, states[:, 5] / 2
        states[:, 0] = np.clip(states[:, 0], half_w, config.image_width - half_w)
        states[:, 2] = np.clip(states[:, 2], half_h, config.image_height - half_h)
        height_scale = self.zone_height_scales[zones]
        aspect_ratio = self.zone_aspect_ratios[zones]
        nominal = nominal_size(states[:, 2], config, height_scale, aspect_ratio)
        own = np.log(states[:, 4:6] / np.maximum(nominal, MIN_BOX_SIDE))
        self.state = np.concatenate([self.state, states])
        self.log_scale = np.concatenate([self.log_scale, own])
        self.own_log_scale = np.concatenate([self.own_log_scale, own])
        self.height_scale = np.concatenate([self.height_scale, height_scale])
        self.aspect_ratio = np.concatenate([self.aspect_ratio, aspect_ratio])
        self.age = np.concatenate([self.age, np.zeros(count, np.int64)])
        self.gt_id = np.concatenate([self.gt_id, np.zeros(count, np.int64)])
        return zones

    def _record(self, frame: int, new_zones: np.ndarray) -> None:
        config, rng, state = self.config, self.rng, self.state
        t = frame - 1
        n = state.shape[0]
        unlabelled = np.flatnonzero(self.gt_id == 0)
        self.gt_id[unlabelled] = self.next_id + np.arange(unlabelled.size)
        self.next_id += unlabelled.size
        num_new = new_zones.size
        if num_new:
            self.births.append(
                (
                    np.full(num_new, frame),
                    self.gt_id[n - num_new :].copy(),
                    new_zones,
                    state[n - num_new :].copy(),
                )
            )
        self.num_births[t] = num_new
        self.num_targets[t] = n

        centre_boxes = state[:, [0, 2, 4, 5]]
        boxes = cxcywh_to_xywh(centre_boxes)
        occluded = occluded_fraction(boxes) > config.occlusion_threshold
        p_detect = np.where(occluded, config.occluded_detection_prob, config.detection_prob)
        detected = rng.random(n) < p_detect
        order = np.argsort(self.gt_id)
        self.gt_rows.append(
            (
                np.full(n, frame),
                self.gt_id[order],
                _round(boxes[order], BOX_DECIMALS),
                state[order].copy(),
                occluded[order],
                detected[order],
            )
        )

        s_w, s_h = config.measurement_noise
        true_boxes = centre_boxes[detected]
        noise_std = true_boxes[:, [2, 3, 2, 3]] * np.array([s_w, s_h, s_w, s_h])
        measured = true_boxes + rng.normal(size=true_boxes.shape) * noise_std
        measured_ids = self.gt_id[detected]
        # random numbers drawn only when a scene uses the feature (old scenes unchanged)
        if config.misplaced_detection_prob > 0:
            bad = rng.random(measured.shape[0]) < config.misplaced_detection_prob
            measured[bad] = badly_placed_boxes(rng, true_boxes[bad])
        if config.extra_detection_prob > 0:
            extra = rng.random(measured.shape[0]) < config.extra_detection_prob
            measured = np.concatenate([measured, badly_placed_boxes(rng, true_boxes[extra])])
            measured_ids = np.concatenate([measured_ids, measured_ids[extra]])
        clutter, clutter_source = self._clutter(t)
        all_boxes = np.concatenate([measured, clutter])
        sources = np.concatenate([np.full(measured.shape[0], -1), clutter_source])
        target_ids = np.concatenate([measured_ids, np.full(clutter.shape[0], -1)])
        score_true = rng.beta(*config.target_score, size=measured.shape[0])
        score_clutter = rng.beta(*config.clutter_score, size=clutter.shape[0])
        scores = np.concatenate([score_true, score_clutter])
        perm = rng.permutation(all_boxes.shape[0])
        self.num_target_detections[t] = measured.shape[0]
        self.det_rows.append(
            (
                np.full(perm.size, frame),
                self._image_boxes(all_boxes[perm]),
                np.clip(np.round(scores[perm], SCORE_DECIMALS), 10.0**-SCORE_DECIMALS, 1.0),
                target_ids[perm],
                sources[perm],
            )
        )

    def _clutter(self, t: int) -> tuple[np.ndarray, np.ndarray]:
        """Clutter boxes ``(cx, cy, w, h)`` of one frame and the source of each."""
        config, rng = self.config, self.rng
        num_sources = self.source_rates.size
        rates = self.source_rates
        if self.sources_flicker:
            self._switch_sources(t)
            rates = np.where(self.source_on, rates, 0.0)
        counts = np.append(rng.poisson(rates), rng.poisson(config.uniform_clutter_rate))
        self.num_clutter[t] = counts
        source = np.repeat(np.arange(num_sources + 1), counts)
        from_sources = source[source < num_sources]
        localised = self.source_means[from_sources] + self.source_stds[from_sources] * rng.normal(
            size=(from_sources.size, 4)
        )
        if self.sources_have_extent:
            offsets = rng.uniform(-1.0, 1.0, size=(from_sources.size, 2))
            localised[:, :2] += self.source_extents[from_sources] * offsets
        lower = np.array([0.0, 0.0, *config.min_box_size])
        upper = np.array([config.image_width, config.image_height, *config.max_box_size])
        uniform = rng.uniform(lower, upper, size=(counts[-1], 4))
        return np.concatenate([localised, uniform]), source

    def _switch_sources(self, t: int) -> None:
        """Flicker: the sources' on/off states of frame ``t + 1`` (a two-state Markov chain).

        Frame 1 draws the stationary law (on with probability ``duty_cycle``); later frames
        switch an on source off with probability ``1 / on_frames`` and an off source on with
        probability ``1 / off_frames``. A source that does not flicker stays on.
        """
        draws = self.rng.random(self.source_on.size)
        if t == 0:
            self.source_on = draws < self.source_duty
        else:
            switch = np.where(self.source_on, self.source_switch_off, self.source_switch_on)
            self.source_on = self.source_on ^ (draws < switch)
        self.clutter_source_on[t] = self.source_on

    def _image_boxes(self, centre_boxes: np.ndarray) -> np.ndarray:
        """Measured ``(cx, cy, w, h)`` -> rounded ``(x, y, w, h)`` clipped to the image."""
        sizes = np.maximum(centre_boxes[:, 2:], MIN_BOX_SIDE)
        corners = np.concatenate(
            [centre_boxes[:, :2] - sizes / 2, centre_boxes[:, :2] + sizes / 2], 1
        )
        image = np.array([self.config.image_width, self.config.image_height], np.float64)
        top_left = np.clip(corners[:, :2], 0.0, image - 1.0)
        bottom_right = np.clip(corners[:, 2:], top_left + 1.0, image)
        top_left = _round(top_left, BOX_DECIMALS)
        bottom_right = _round(bottom_right, BOX_DECIMALS)
        return np.concatenate([top_left, _round(bottom_right - top_left, BOX_DECIMALS)], 1)

    def scene(self, seed: int) -> SyntheticScene:
        config = self.config
        gt = [np.concatenate(column) for column in zip(*self.gt_rows, strict=True)]
        det = [np.concatenate(column) for column in zip(*self.det_rows, strict=True)]
        gt_frames, gt_ids, gt_boxes, gt_states, gt_occluded, gt_detected = gt
        det_frames, det_boxes, det_scores, det_target_ids, det_sources = det
        if self.births:
            birth_frames, birth_ids, birth_zones, birth_states = (
                np.concatenate(column) for column in zip(*self.births, strict=True)
            )
        else:
            birth_frames, birth_ids = np.zeros(0, np.int64), np.zeros(0, np.int64)
            birth_zones, birth_states = np.zeros(0, np.int64), np.zeros((0, 6))
        gt_table = MotTable.from_arrays(gt_frames, gt_ids, gt_boxes, np.ones(gt_frames.size))
        det_table = MotTable.from_arrays(
            det_frames, np.full(det_frames.size, -1), det_boxes, det_scores
        )
        info = SequenceInfo(
            name=config.name if config.name is not None else f"synthetic-{seed}",
            seq_length=config.num_frames,
            im_width=config.image_width,
            im_height=config.image_height,
            frame_rate=config.frame_rate,
        )
        return SyntheticScene(
            seed=seed,
            config=config,
            info=info,
            det_table=det_table,
            gt_table=gt_table,
            detections=pad_detections(det_table, 1, config.num_frames),
            ground_truth=pad_ground_truth(gt_table, 1, config.num_frames),
            birth_intensity=birth_intensity(config),
            clutter_intensity=clutter_intensity(config),
            det_target_ids=det_target_ids.astype(np.int64),
            det_clutter_source=det_sources.astype(np.int64),
            gt_states=gt_states,
            gt_occluded=gt_occluded,
            gt_detected=gt_detected,
            birth_frames=birth_frames.astype(np.int64),
            birth_ids=birth_ids.astype(np.int64),
            birth_zones=birth_zones.astype(np.int64),
            birth_states=birth_states,
            num_targets=self.num_targets,
            num_births=self.num_births,
            num_target_detections=self.num_target_detections,
            num_clutter=self.num_clutter,
            clutter_source_on=self.clutter_source_on,
        )


def _zone_probabilities(config: SceneConfig) -> np.ndarray:
    weights = np.array([zone.weight for zone in config.zones], np.float64)
    return weights / weights.sum() if weights.size else weights


def _intensity(magnitude, uniform_weight, lower, upper, weights, means, covs) -> Intensity:
    return Intensity(
        magnitude=jnp.asarray(magnitude, jnp.float32),
        uniform_weight=jnp.asarray(uniform_weight, jnp.float32),
        lower=jnp.asarray(lower, jnp.float32),
        upper=jnp.asarray(upper, jnp.float32),
        weights=jnp.asarray(weights, jnp.float32),
        means=jnp.asarray(means, jnp.float32),
        covs=jnp.asarray(covs, jnp.float32),
    )


def _metadata(scene: SyntheticScene) -> dict:
    """Zones, sources and the configuration, stored beside the true intensities."""
    config = scene.config
    zones, sources = config.zones, config.clutter_sources
    return {
        "source": "synthetic scene (true context)",
        "seed": int(scene.seed),
        "config": config_to_dict(config),
        "image_size": [config.image_width, config.image_height],
        "zone_names": [zone.name for zone in zones],
        "zone_exit": [bool(zone.exit) for zone in zones],
        "source_names": [source.name for source in sources],
        "source_rates": [float(source.rate) for source in sources],
        "uniform_clutter_rate": float(config.uniform_clutter_rate),
    }


def _round(values: np.ndarray, decimals: int) -> np.ndarray:
    return np.round(values, decimals) + 0.0


def _rate(flags: np.ndarray) -> float:
    return float(flags.mean()) if flags.size else float("nan")
