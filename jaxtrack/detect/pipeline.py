"""Video to detections: background subtraction, blobs, perspective splitting, person boxes.

:func:`detect_video` runs one detector over a frame span of a video (or image folder):

1. Frames are shrunk by ``scale`` (default 0.5: 384x288 for PETS 2009; people stay 15-60
   pixels tall, and every later step costs a quarter).
2. A foreground mask per frame from the chosen method (:data:`METHODS`):
   ``"horprasert"`` (:mod:`~jaxtrack.detect.horprasert`; background statistics from
   ``train_frames`` frames spread evenly over the span: robust median / MAD, so people
   walking through the training frames do not enter the model; foreground and dark
   foreground are kept, shadows and highlights dropped) or ``"mog2"`` (OpenCV's Gaussian
   mixture background subtractor with its shadow detection, Zivkovic 2004/2006, warmed up on
   the training frames' per-pixel median and then the training frames themselves, so that
   the first frame seen is a clean background; shadow pixels dropped).
3. Mask cleaning (:func:`~jaxtrack.detect.blobs.clean_mask`): an opening with a vertical
   line (removes thin horizontal structures such as a waving barrier tape, which would
   otherwise join people into one blob) and a closing with a tall ellipse.
4. Blobs of at least ``min_area`` pixels (full-resolution pixels).
5. The perspective prior (:mod:`~jaxtrack.detect.perspective`) is learned from all the
   span's blobs; blobs too wide or too tall for one person at their row are split; parts
   shorter than ``min_height_ratio`` of a person at their row are dropped.
6. Person boxes: thin silhouettes are widened to the pedestrian aspect ratio
   (:data:`~jaxtrack.detect.perspective.PERSON_ASPECT`) about their centre column.

The score of a detection is ``min(1, h / expected_height)`` at its row: 1 for a whole
person, less for a part of one.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import cv2
import numpy as np
from tqdm import tqdm

from jaxtrack.detect.blobs import clean_mask, extract_blobs
from jaxtrack.detect.horprasert import classify, fit_horprasert, foreground_mask
from jaxtrack.detect.perspective import (
    PERSON_ASPECT,
    SPLIT_FACTOR,
    PerspectivePrior,
    fit_perspective,
    person_box,
    split_blob,
)
from jaxtrack.errors import InputError
from jaxtrack.io.motchallenge import MotTable, parse_frame_span
from jaxtrack.io.video import VideoReader

#: Detector methods of :func:`detect_video` (``jaxtrack detect --method``).
METHODS = ("horprasert", "mog2")


class DetectorConfig(NamedTuple):
    """Settings of :func:`detect_video` (the defaults are the documented configuration).

    Attributes:
        method: one of :data:`METHODS`.
        scale: image scale at which the masks are computed.
        train_frames: frames spread over the span for the background statistics (and the
            MOG2 warm-up).
        detection_rate: Horprasert's automatic threshold rate.
        mog2_history: frames of MOG2's history.
        mog2_var_threshold: MOG2's squared Mahalanobis distance threshold.
        open_size: ``(width, height)`` of the opening's rectangle, processing pixels.
        close_size: ``(width, height)`` of the closing's ellipse, processing pixels.
        min_area: smallest blob, full-resolution pixels.
        split: split blobs with the perspective prior.
        split_factor: sizes of one person that make a group.
        min_height_ratio: parts shorter than this fraction of a person at their row are
            dropped (only with ``split``).
        person_aspect: width / height that thin boxes are widened to (0: none).
    """

    method: str = "horprasert"
    scale: float = 0.5
    train_frames: int = 50
    detection_rate: float = 0.995
    mog2_history: int = 500
    mog2_var_threshold: float = 16.0
    open_size: tuple[int, int] = (1, 5)
    close_size: tuple[int, int] = (3, 11)
    min_area: int = 240
    split: bool = True
    split_factor: float = SPLIT_FACTOR
    min_height_ratio: float = 0.5
    person_aspect: float = PERSON_ASPECT


class VideoDetections(NamedTuple):
    """What :func:`detect_video` found.

    Attributes:
        table: MOTChallenge detections ``frame,-1,x,y,w,h,score`` in full-resolution pixels.
        prior: the perspective prior (full-resolution pixels), or None without splitting.
        frames: ``(first, last)`` 1-based span detected.
        fps: the reader's frame rate (the override, else the file's), or None.
        size: ``(width, height)`` of the frames.
    """

    table: MotTable
    prior: PerspectivePrior | None
    frames: tuple[int, int]
    fps: float | None
    size: tuple[int, int]


def check_config(config: DetectorConfig) -> None:
    """Raises InputError for an unknown method or a setting out of range."""
    if config.method not in METHODS:
        raise InputError(f"unknown method {config.method!r}; known: {', '.join(METHODS)}")
    if not 0 < config.scale <= 1:
        raise InputError(f"scale must lie in (0, 1], got {config.scale}")
    if config.train_frames < 3:
        raise InputError(f"train_frames must be >= 3, got {config.train_frames}")
    if config.min_area < 1:
        raise InputError(f"min_area must be >= 1, got {config.min_area}")
    if config.split_factor <= 1:
        raise InputError(f"split_factor must be > 1, got {config.split_factor}")


def shrink(frame: np.ndarray, scale: float) -> np.ndarray:
    """The frame at ``scale`` (area averaging), or itself at scale 1."""
    if scale == 1:
        return frame
    return cv2.resize(frame, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)


def training_frames(reader: VideoReader, span: tuple[int, int], count: int, scale: float):
    """``count`` frames spread evenly over the span (all of them if it is shorter), shrunk."""
    numbers = np.unique(np.linspace(span[0], span[1], count).round().astype(int))
    return np.stack([shrink(reader.read(int(k)), scale) for k in numbers])


def mask_function(config: DetectorConfig, training: np.ndarray) -> Callable:
    """The per-frame ``frame -> bool foreground mask`` of a method, trained on ``training``.

    MOG2 is stateful (it keeps learning): call the function on consecutive frames.
    """
    if config.method == "horprasert":
        model = fit_horprasert(training, config.detection_rate)
        return lambda frame: foreground_mask(classify(model, frame))
    subtractor = cv2.createBackgroundSubtractorMOG2(
        history=config.mog2_history,
        varThreshold=config.mog2_var_threshold,
        detectShadows=True,
    )
    subtractor.apply(np.median(training, axis=0).astype(np.uint8))
    for frame in training:
        subtractor.apply(frame)
    return lambda frame: subtractor.apply(frame) == 255


def detect_video(
    source: str | VideoReader,
    frames: tuple[int, int] | None = None,
    config: DetectorConfig | None = None,
    progress: bool = False,
) -> VideoDetections:
    """Detects people in a frame span of a video or image folder.

    Args:
        source: a video file / image folder, or an open :class:`VideoReader` (its fps
            override is kept).
        frames: ``(first, last)`` 1-based inclusive span; default: all frames.
        config: detector settings (default :class:`DetectorConfig`).
        progress: show a progress bar.

    Returns:
        The detections.

    Raises:
        FileFormatError: the video is missing, unreadable or a frame does not decode.
        InputError: a bad span or setting, or (with splitting) too few person-shaped blobs
            to learn the perspective prior.
    """
    config = config or DetectorConfig()
    check_config(config)
    if isinstance(source, VideoReader):
        return _detect(source, frames, config, progress)
    with VideoReader(source) as reader:
        return _detect(reader, frames, config, progress)


def _detect(reader, frames, config: DetectorConfig, progress: bool) -> VideoDetections:

    span = parse_frame_span(frames, reader.num_frames)
    foreground = mask_function(
        config, training_frames(reader, span, config.train_frames, config.scale)
    )
    min_area = max(round(config.min_area * config.scale**2), 1)
    numbers = range(span[0], span[1] + 1)
    if progress:
        numbers = tqdm(numbers, desc=f"detect ({config.method})", unit="frame")
    per_frame = []
    for k in numbers:
        mask = foreground(shrink(reader.read(k), config.scale))
        per_frame.append(
            extract_blobs(clean_mask(mask, config.open_size, config.close_size), min_area)
        )
    boxes, prior = blob_boxes(per_frame, config)
    frame_numbers = np.concatenate(
        [np.full(len(b), span[0] + t) for t, b in enumerate(boxes)] + [np.zeros(0, int)]
    )
    all_boxes = np.concatenate([*boxes, np.zeros((0, 4))])
    scores = _scores(all_boxes, prior)
    table = MotTable.from_arrays(
        frame_numbers,
        np.full(len(frame_numbers), -1),
        finish_boxes(all_boxes, config) / config.scale,
        np.round(scores, 4),
        path=str(reader.path),
    )
    full_prior = None
    if prior is not None:
        full_prior = prior._replace(intercept=prior.intercept / config.scale)
    return VideoDetections(table, full_prior, span, reader.fps, (reader.width, reader.height))


def blob_boxes(per_frame: list, config: DetectorConfig):
    """Boxes of each frame's blobs after perspective splitting, and the prior used.

    Args:
        per_frame: the :class:`~jaxtrack.detect.blobs.Blobs` of each frame.
        config: the settings (``split``, ``split_factor``, ``min_height_ratio``).

    Returns:
        ``(boxes, prior)``: a ``[num_boxes_t, 4]`` array per frame (processing pixels) and
        the :class:`PerspectivePrior` (None without splitting).
    """
    if not config.split:
        return [b.boxes for b in per_frame], None
    prior = fit_perspective(np.concatenate([b.boxes for b in per_frame] + [np.zeros((0, 4))]))
    out = []
    for blobs in per_frame:
        parts = [
            split_blob(box, crop, prior, config.split_factor)
            for box, crop in zip(blobs.boxes, blobs.crops, strict=True)
        ]
        parts = np.concatenate(parts) if parts else np.zeros((0, 4))
        tall_enough = parts[:, 3] >= config.min_height_ratio * prior.height(
            parts[:, 1] + parts[:, 3]
        )
        out.append(parts[tall_enough])
    return out, prior


def finish_boxes(boxes: np.ndarray, config: DetectorConfig) -> np.ndarray:
    """Widens thin boxes to ``config.person_aspect`` (none when 0)."""
    if config.person_aspect <= 0:
        return boxes
    return person_box(boxes, config.person_aspect)


def _scores(boxes: np.ndarray, prior: PerspectivePrior | None) -> np.ndarray:
    """``min(1, h / expected_height)``; 1 without a prior."""
    if prior is None:
        return np.ones(len(boxes))
    return np.minimum(boxes[:, 3] / prior.height(boxes[:, 1] + boxes[:, 3]), 1.0)
