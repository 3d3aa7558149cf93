"""The experiments of PHD-context Sec. V as library code, run by ``jaxtrack experiment NAME``.

* :mod:`~jaxtrack.experiments.common`: output folders, train/test splits of a sequence
  (the synthetic default scene or a MOTChallenge folder), scoring tracker rows, CSV and
  markdown writing.
* :mod:`~jaxtrack.experiments.ablation`: Fig. 14, the context variants UM, GM, A1-A6 and
  their % score difference with respect to UM.
* :mod:`~jaxtrack.experiments.comparison`: Fig. 16, the PHD tracker with learned context
  against the Kalman data-association baseline and its SORT-like preset.
"""
