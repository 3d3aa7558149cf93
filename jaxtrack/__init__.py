"""jaxtrack: a JAX toolkit for context-aware multi-object tracking.

The flat public API (optax style)::

    import jaxtrack as jt

    seq = jt.load_sequence("../shared/data/mot15/TUD-Campus")
    filt, params = jt.build_tracker(jt.PHDConfig(), seq.info)
    _, info = jt.run(filt, jax.random.key(0), params, seq.detections)
    (rows,) = jt.track_sequences([seq], jt.PHDConfig())
"""

from jaxtrack.configs import TrackerConfig, load_config_file
from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.filters.base import Filter, run
from jaxtrack.filters.kalman import kalman_filter
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd import PHDInfo, PHDParams, PHDState, phd_filter
from jaxtrack.filters.phd_tracker import VARIANTS, Context, PHDConfig, phd_params
from jaxtrack.filters.registry import TRACKERS, build_tracker
from jaxtrack.io import MotSequence, MotTable, SequenceInfo, load_sequence, write_results
from jaxtrack.metrics.evaluate import evaluate_sequence
from jaxtrack.parameters import ParameterProperties
from jaxtrack.pipelines.context import learn_context
from jaxtrack.pipelines.runtime import (
    use_compilation_cache,
    use_cpu_cores,
    use_cpu_threads,
    use_cpu_vector_width,
)
from jaxtrack.pipelines.sweep import batch_params, magnitude_grid, product_grid, sweep, sweep_frames
from jaxtrack.pipelines.tracking import track_sequences
from jaxtrack.pipelines.tuner import tune
from jaxtrack.pipelines.tuning import tune_sequence
from jaxtrack.tuning import likelihood_objective, parameter_space, supervised_objective
from jaxtrack.types import Detections, GroundTruth, Tracks

__version__ = "0.1.0"

__all__ = [
    "TRACKERS",
    "VARIANTS",
    "Context",
    "Detections",
    "FileFormatError",
    "Filter",
    "GroundTruth",
    "InputError",
    "KalmanConfig",
    "MotSequence",
    "MotTable",
    "PHDConfig",
    "PHDInfo",
    "PHDParams",
    "PHDState",
    "ParameterProperties",
    "SequenceInfo",
    "TrackerConfig",
    "Tracks",
    "batch_params",
    "build_tracker",
    "evaluate_sequence",
    "kalman_filter",
    "learn_context",
    "likelihood_objective",
    "load_config_file",
    "load_sequence",
    "magnitude_grid",
    "parameter_space",
    "phd_filter",
    "phd_params",
    "product_grid",
    "run",
    "supervised_objective",
    "sweep",
    "sweep_frames",
    "track_sequences",
    "tune",
    "tune_sequence",
    "use_compilation_cache",
    "use_cpu_cores",
    "use_cpu_threads",
    "use_cpu_vector_width",
    "write_results",
]
