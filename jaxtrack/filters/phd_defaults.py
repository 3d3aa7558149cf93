"""Default uniform intensities and a default pedestrian configuration of the PHD tracker.

The defaults are scale-free: noise is relative to the box size (SDV), intensities are uniform
over volumes derived from the image size, and the velocity range of the birth intensity from
the image height and the frame rate (:mod:`jaxtrack.context.intensity`), so that one
configuration serves 640x480 to 1920x1080 images at 7 to 30 frames per second.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxtrack.association.labelling import LabelParams
from jaxtrack.context.intensity import (
    birth_speed_limit,
    uniform_birth_intensity,
    uniform_clutter_intensity,
)
from jaxtrack.context.scores import identity_calibration
from jaxtrack.filters.phd import PHDParams, TargetClutter

#: SDV motion noise ``(sigma_n1, sigma_n2, sigma_nw, sigma_nh)``, relative to the box size.
DEFAULT_MOTION_NOISE_STD = (0.05, 0.02, 0.05, 0.05)
#: SDV measurement noise ``(s_1, s_2, s_w, s_h)``, relative to the box size.
DEFAULT_MEASUREMENT_NOISE_STD = (0.15, 0.08, 0.25, 0.15)
#: Detection probability ``pD = 1 - pM``.
DEFAULT_DETECTION_PROB = 0.8
#: Relative spread ``(s_1, s_2, s_w, s_h)`` of the detections a target generates besides its
#: own (:class:`~jaxtrack.filters.phd.TargetClutter`; used only with a rate > 0, which a
#: learned context sets together with its own spread): twice the likelihood's.
DEFAULT_TARGET_CLUTTER_NOISE_STD = tuple(2 * s for s in DEFAULT_MEASUREMENT_NOISE_STD)
#: Survival probability ``e(x)`` per frame.
DEFAULT_SURVIVAL_PROB = 0.99


def default_phd_params(
    im_width: float,
    im_height: float,
    frame_rate: float | None = None,
    birth_rate: float = 0.2,
    clutter_rate: float = 1.0,
) -> PHDParams:
    """A pedestrian configuration with uniform (UM) intensities.

    Chosen for public pedestrian detections (Faster R-CNN, score >= 0.5) and kept the same for
    every sequence: the measurement noise follows the spread of such detections around the
    ground truth (about 0.15 w and 0.08 h for the centre, 0.25 w and 0.15 h for the size);
    the motion noise lets the velocity change by a few percent of the box size per frame;
    ``pD = 0.8``; a track is output once a detection of score >= 0.97 confirms it (detector
    false positives recur at the same place, so the uniform-clutter model alone cannot
    reject them); the birth velocity range is ``0.4 * im_height / frame_rate`` pixels per
    frame.

    Args:
        im_width: image width, pixels.
        im_height: image height, pixels.
        frame_rate: frames per second (default
            :data:`~jaxtrack.context.intensity.DEFAULT_FRAME_RATE`).
        birth_rate: ``lambda_s``, expected births per frame.
        clutter_rate: ``lambda_r``, expected false detections per frame.

    Returns:
        The parameters.
    """
    max_speed = birth_speed_limit(im_height, frame_rate)
    return PHDParams(
        motion_noise_std=jnp.array(DEFAULT_MOTION_NOISE_STD),
        measurement_noise_std=jnp.array(DEFAULT_MEASUREMENT_NOISE_STD),
        detection_prob=jnp.asarray(DEFAULT_DETECTION_PROB),
        survival_prob=jnp.asarray(DEFAULT_SURVIVAL_PROB),
        birth_intensity=uniform_birth_intensity(birth_rate, im_width, im_height, max_speed),
        initial_intensity=uniform_birth_intensity(birth_rate, im_width, im_height, max_speed),
        clutter_intensity=uniform_clutter_intensity(clutter_rate, im_width, im_height),
        score_weight=jnp.asarray(0.0),
        mass_threshold=jnp.asarray(0.5),
        labelling=LabelParams(
            min_iou=jnp.asarray(0.3),
            max_missed_frames=jnp.asarray(10.0),
            confirm_score=jnp.asarray(0.97),
            new_track_max_iou=jnp.asarray(0.3),
            velocity_smoothing=jnp.asarray(0.8),
            score_calibration=jax.tree.map(jnp.asarray, identity_calibration()),
        ),
        target_clutter=TargetClutter(
            rate=jnp.asarray(0.0), noise_std=jnp.array(DEFAULT_TARGET_CLUTTER_NOISE_STD)
        ),
    )
