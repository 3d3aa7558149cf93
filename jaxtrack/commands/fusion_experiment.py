"""``jaxtrack experiment fusion``: its help and run (logic in :mod:`jaxtrack.experiments.fusion`;
registered in :mod:`jaxtrack.commands.experiment`)."""

from __future__ import annotations

import argparse
import functools

from jaxtrack.commands.cmt_ablation import add_video_arguments
from jaxtrack.commands.hierarchical_experiment import SEEDS, run_video_experiment
from jaxtrack.experiments.cmt_ablation import BEST_PEER_IDF1, PETS_VIDEO
from jaxtrack.experiments.fusion import BEST_PEER_MT, TABLE_COLUMNS, run_experiment
from jaxtrack.filters.fusion_tracker import INIT_RULES

HELP = "Fusion tracker: the paper's Table 1 ablation and Table 4 row, with PHD as baseline"
QUICK_HELP = (
    "smoke run: TUD-Campus and the first --seeds scene, their first frames; Proposed and PHD "
    "only (and the True identities reference)"
)
DESCRIPTION = f"""\
The Fusion tracker (SPEC section 3): the paper's Table 1 ablation and Table 4 row.

Trackers, as `jaxtrack track --tracker fusion` runs them with default configurations and
--seed: each pool member alone (Detector, Classifier, Predictor), the three members with the
naive mean fusion (Naive fusion) and with the proposed fusion (Proposed); and the PHD tracker
(default configuration), the motion-only baseline. The Fusion tracker learns its context
(zones, motion models, voting thresholds calibrated against the ground truth) on the first
half of each sequence. Beside them a reference, not a tracker: True identities, the same
detections mapped to the ground truth (IoU >= 0.5) under its identities, i.e. perfect
association with the detector's own boxes (no switch, no false positive; its MT and FM say
what the detections alone allow).

Sequences: PETS09-S2L1 (frames: --data/{PETS_VIDEO}), TUD-Campus and TUD-Stadtmitte (their
.mp4), and the scripted video scenes of --seeds (default {SEEDS}: held out, never used to
tune any default), written to OUT/scenes/video-SEED; each tracked whole with two detection
sources: det (its own detections: MOT15's det.txt, the scenes' simulated detector) and bs
(the toolkit's background-subtraction detector on its frames, default settings). Every run
is scored on the whole sequence (the paper's protocol for its Table 4) and on the held-out
frames after the training half.

Writes into --out: table.md (PETS09-S2L1 beside the paper's Table 4 row; MT/PT/ML in % and
counts, FM, IDS, MOTA/IDF1/HOTA per sequence, source and protocol, pooled over the MOT15
sequences and over the scenes; the paper's Table 1 and the off-the-shelf peers quoted; the
issue's goals as PASS/FAIL: Table 4 matched on PETS09-S2L1 with det, the ablation's shape on
every sequence, IDF1 > {BEST_PEER_IDF1} and MT > {BEST_PEER_MT} pooled over the MOT15 videos,
IDF1 above PHD's on the scenes), results.json (the same with the configurations, training
spans, what was learned, run times) and sequences/SEQ/SOURCE/TRACKER.txt (every result; the
bs detections as det.txt). Logic: jaxtrack.experiments.fusion.

examples:
  jaxtrack experiment fusion --out /tmp/fusion
  jaxtrack experiment fusion --out /tmp/fusion-q --quick --seeds 101
  jaxtrack experiment fusion --out /tmp/fusion-cost --init-rule cost"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The video experiments' arguments (:func:`~jaxtrack.commands.cmt_ablation.
    add_video_arguments`) and ``--init-rule``."""
    add_video_arguments(parser)
    parser.add_argument(
        "--init-rule",
        choices=INIT_RULES,
        default="share",
        help="how every Fusion tracker calibrates th_init on its training span: 'share' (the "
        "paper's: the smallest rejecting 99%% of the detector's false-positive runs; default) "
        "or 'cost' (the fewest false-target and late-start frames; FusionConfig.init_rule)",
    )


def run(args: argparse.Namespace) -> int:
    """Runs the experiment on the parsed arguments; prints the table and the goals."""
    experiment = functools.partial(run_experiment, init_rule=args.init_rule)
    return run_video_experiment(args, experiment, TABLE_COLUMNS)
