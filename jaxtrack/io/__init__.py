"""File input/output: MOTChallenge folders and result files."""

from jaxtrack.io.motchallenge import (
    MotSequence,
    MotTable,
    SequenceInfo,
    load_sequence,
    pad_detections,
    pad_ground_truth,
    parse_frame_span,
    read_mot_file,
    read_seqinfo,
    write_mot_file,
    write_results,
    write_seqinfo,
)

__all__ = [
    "MotSequence",
    "MotTable",
    "SequenceInfo",
    "load_sequence",
    "pad_detections",
    "pad_ground_truth",
    "parse_frame_span",
    "read_mot_file",
    "read_seqinfo",
    "write_mot_file",
    "write_results",
    "write_seqinfo",
]
