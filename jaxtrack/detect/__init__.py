"""Video front end: background subtraction (Horprasert, MOG2) to person detections.

:func:`detect_video` is the whole pipeline (``jaxtrack detect``); the pieces are
:mod:`~jaxtrack.detect.horprasert` (colour model), :mod:`~jaxtrack.detect.blobs` (mask
cleaning, connected components, boxes, ellipses), :mod:`~jaxtrack.detect.perspective`
(person size by image row, group splitting) and :mod:`~jaxtrack.detect.sequence` (a video's
detections as a :class:`~jaxtrack.io.MotSequence` for the tracker and the context learner).
"""

from jaxtrack.detect.blobs import Blobs, clean_mask, extract_blobs
from jaxtrack.detect.horprasert import HorprasertModel, classify, fit_horprasert, foreground_mask
from jaxtrack.detect.perspective import PerspectivePrior, fit_perspective, split_blob
from jaxtrack.detect.pipeline import METHODS, DetectorConfig, VideoDetections, detect_video
from jaxtrack.detect.sequence import video_info, video_sequence

__all__ = [
    "METHODS",
    "Blobs",
    "DetectorConfig",
    "HorprasertModel",
    "PerspectivePrior",
    "VideoDetections",
    "classify",
    "clean_mask",
    "detect_video",
    "extract_blobs",
    "fit_horprasert",
    "fit_perspective",
    "foreground_mask",
    "split_blob",
    "video_info",
    "video_sequence",
]
