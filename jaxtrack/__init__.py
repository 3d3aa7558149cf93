"""jaxtrack: a JAX toolkit for context-aware multi-object tracking."""

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.io import MotSequence, MotTable, SequenceInfo, load_sequence, write_results
from jaxtrack.types import Detections, GroundTruth, Tracks

__version__ = "0.1.0"

__all__ = [
    "Detections",
    "FileFormatError",
    "GroundTruth",
    "InputError",
    "MotSequence",
    "MotTable",
    "SequenceInfo",
    "Tracks",
    "load_sequence",
    "write_results",
]
