"""The experiments of PHD-context Sec. V as library code, run by ``jaxtrack experiment NAME``.

* :mod:`~jaxtrack.experiments.common`: output folders, train/test splits of a sequence
  (the synthetic default scene or a MOTChallenge folder), scoring tracker rows, CSV and
  markdown writing.
* :mod:`~jaxtrack.experiments.ablation`: Fig. 14, the context variants UM, GM, A1-A6 and
  their % score difference with respect to UM.
* :mod:`~jaxtrack.experiments.comparison`: Fig. 16, the PHD tracker with learned context
  against the Kalman data-association baseline and its SORT-like preset.
* :mod:`~jaxtrack.experiments.context_gap`: UM vs GM on the scene bank's families.
* :mod:`~jaxtrack.experiments.context_generalisation`: issue 15's experiment, UM, GM, A1-A6
  and GM+tuned on the scene bank, PETS09-S2L1, TUD-Stadtmitte and the video detector's
  output, with the relative MOTA gain per family and the goals checked.
"""
