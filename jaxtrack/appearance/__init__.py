"""Appearance features of image regions for the CMT, Hierarchical and Fusion trackers.

Pure JAX (core layer): every per-box function runs under ``jit`` and ``lax.scan`` and
``vmap``s over boxes (particles, targets). Frames enter as uint8 ``H x W x 3`` RGB.

* :mod:`~jaxtrack.appearance.patches`: fixed-size sampling of a box (bilinear, nearest);
* :mod:`~jaxtrack.appearance.colour`: RGB, normalised rg, HSV, Collins' 49 combinations;
* :mod:`~jaxtrack.appearance.histograms`: quantisation, joint bins, band counts, kernel;
* :mod:`~jaxtrack.appearance.regions`: top/bottom halves, Fusion's split, shape feature;
* :mod:`~jaxtrack.appearance.features`: the papers' region histograms of one box;
* :mod:`~jaxtrack.appearance.similarity`: Bhattacharyya coefficient, distance, likelihood;
* :mod:`~jaxtrack.appearance.mutual_information`: CMT's feature weights (eq. 13-17);
* :mod:`~jaxtrack.appearance.variance_ratio`: Collins' ranking, M current + N long-run;
* :mod:`~jaxtrack.appearance.model`: recursive mean histograms with a distance gate.
"""

from jaxtrack.appearance.colour import (
    LINEAR_COMBINATION_WEIGHTS,
    hsv,
    linear_combinations,
    normalised_rg,
    rgb,
)
from jaxtrack.appearance.features import (
    linear_combination_histograms,
    profile_histograms,
    top_bottom_histograms,
)
from jaxtrack.appearance.histograms import (
    band_counts,
    band_histograms,
    epanechnikov,
    joint_bins,
    marginals,
    normalise,
    num_bins,
    quantise,
)
from jaxtrack.appearance.model import AppearanceModel, init_model, update_model, within_gate
from jaxtrack.appearance.mutual_information import (
    chance_information,
    decay_update,
    feature_values,
    feature_weights,
    field_of_context,
    multiresolution_mutual_information,
    mutual_information,
    quantise_values,
)
from jaxtrack.appearance.patches import (
    DEFAULT_PATCH_SHAPE,
    Patch,
    sample_nearest,
    sample_patch,
    sample_points,
)
from jaxtrack.appearance.regions import Split, aspect_ratio, best_split, halves
from jaxtrack.appearance.similarity import (
    bhattacharyya_coefficient,
    bhattacharyya_distance,
    histogram_likelihood,
)
from jaxtrack.appearance.variance_ratio import (
    FeaturePool,
    init_pool,
    log_likelihood_ratio,
    select_features,
    variance_ratio,
)

__all__ = [
    "DEFAULT_PATCH_SHAPE",
    "LINEAR_COMBINATION_WEIGHTS",
    "AppearanceModel",
    "FeaturePool",
    "Patch",
    "Split",
    "aspect_ratio",
    "band_counts",
    "band_histograms",
    "best_split",
    "bhattacharyya_coefficient",
    "bhattacharyya_distance",
    "chance_information",
    "decay_update",
    "epanechnikov",
    "feature_values",
    "feature_weights",
    "field_of_context",
    "halves",
    "histogram_likelihood",
    "hsv",
    "init_model",
    "init_pool",
    "joint_bins",
    "linear_combination_histograms",
    "linear_combinations",
    "log_likelihood_ratio",
    "marginals",
    "multiresolution_mutual_information",
    "mutual_information",
    "normalise",
    "normalised_rg",
    "num_bins",
    "profile_histograms",
    "quantise",
    "quantise_values",
    "rgb",
    "sample_nearest",
    "sample_patch",
    "sample_points",
    "select_features",
    "top_bottom_histograms",
    "update_model",
    "variance_ratio",
    "within_gate",
]
