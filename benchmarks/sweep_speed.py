"""The 9 x 9 UM + GM magnitude sweep on PETS09-S2L1: one sharded, vmapped sweep vs a Python loop.

Learns a context on frames 1:397 (``learn_context(..., birth_from="tracks",
clutter_from="gt")``), then tracks frames 398:795 for 81 ``(lambda_r, lambda_s)`` points
(log-spaced, clutter 0.1..10, birth 0.02..2 per frame) with uniform intensities (UM) and with
the learned context (GM): 162 tracker runs, each scored (MOTA, MOTP, MODA, MODP, IDF1, HOTA,
...). UM's intensities are padded with dead mixture components to GM's size, so both share
one batch and one compile.

* sweep: :func:`jaxtrack.sweep.sweep` on all devices, compile included. On CPU, JAX has one
  device that uses every core (``--host-devices N`` forces N CPU devices instead; on this
  problem size two forced devices on a 2-core machine hang inside XLA's CPU runtime, jaxlib
  0.10.2, while the same sweep on small problems works; so the default is 1);
* loop: the same configurations one at a time through one jitted single-configuration run
  (``jit(run)`` on one device) plus the same scoring; ``--loop-configs K`` times the first
  K of every variant's grid and extrapolates to 162 (stated in the JSON).

Prints JSON with both times and the ratio. The context learning is not timed.
Usage: ``python benchmarks/sweep_speed.py [--host-devices N] [--loop-configs 12]``.
"""

from __future__ import annotations

import argparse
import os
import sys

# XLA reads the device count when jax initialises: parse it before importing jax.
_early = argparse.ArgumentParser(add_help=False)
_early.add_argument("--host-devices", type=int, default=1, help="forced CPU devices (default 1)")
_host_devices = _early.parse_known_args(sys.argv[1:])[0].host_devices
if _host_devices > 1:
    os.environ["XLA_FLAGS"] = (
        os.environ.get("XLA_FLAGS", "") + f" --xla_force_host_platform_device_count={_host_devices}"
    ).strip()

import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import numpy as np  # noqa: E402

from jaxtrack.association.offline import finalise_tracks  # noqa: E402
from jaxtrack.context.learn import learn_context  # noqa: E402
from jaxtrack.filters.base import run  # noqa: E402
from jaxtrack.filters.phd_tracker import DEFAULT_CONFIG, Context, build_filter, tracker_params  # noqa: E402
from jaxtrack.io import MotTable, load_sequence  # noqa: E402
from jaxtrack.metrics.evaluate import evaluate_sequence  # noqa: E402
from jaxtrack.sweep import batch_params, common_shapes, magnitude_grid, sweep  # noqa: E402

DEFAULT_SEQUENCE = Path(__file__).resolve().parents[1].parent / "shared/data/mot15/PETS09-S2L1"
TRAIN, TEST = (1, 397), (398, 795)
CLUTTER_RATES = np.logspace(-1, 1, 9)
BIRTH_RATES = np.logspace(np.log10(0.02), np.log10(2.0), 9)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0], parents=[_early])
    parser.add_argument("--sequence", type=Path, default=DEFAULT_SEQUENCE)
    parser.add_argument("--chunk-size", type=int, default=28, help="configurations per call")
    parser.add_argument(
        "--loop-configs", type=int, default=12, help="loop configurations timed per variant"
    )
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    learned = learn_context(args.sequence, TRAIN, birth_from="tracks", clutter_from="gt")
    context = Context(learned.birth, learned.clutter, learned.metadata)
    test = load_sequence(args.sequence, TEST)
    um = tracker_params(test.info)
    gm = tracker_params(test.info, context=context, variant="GM")
    um, gm = common_shapes([um, gm])
    grid = magnitude_grid(CLUTTER_RATES, BIRTH_RATES)
    batches = [batch_params(p, grid) for p in (um, gm)]
    batched = jax.tree.map(lambda *leaves: np.concatenate(leaves), *batches)
    num_configs = 2 * len(CLUTTER_RATES) * len(BIRTH_RATES)
    filt = build_filter(DEFAULT_CONFIG)
    key = jax.random.PRNGKey(args.seed)

    start = time.perf_counter()
    result = sweep(
        filt,
        batched,
        key,
        test.detections,
        ground_truth=test.gt_table,
        first_frame=test.first_frame,
        chunk_size=args.chunk_size,
        max_gap=DEFAULT_CONFIG["max_gap"],
        progress=True,
    )
    sweep_s = time.perf_counter() - start

    # One configuration at a time on the default (first) device.
    single = jax.jit(lambda k, p: run(filt, k, p, test.detections)[1][:2])
    per_variant = min(args.loop_configs, num_configs // 2)
    timed = [v * (num_configs // 2) + i for v in range(2) for i in range(per_variant)]
    start = time.perf_counter()
    jax.block_until_ready(single(key, jax.tree.map(lambda x: x[0], batched)))
    loop_compile_s = time.perf_counter() - start
    loop_mota = []
    start = time.perf_counter()
    for b in timed:
        tracks, candidates = single(key, jax.tree.map(lambda x, b=b: x[b], batched))
        rows = finalise_tracks(tracks, candidates, DEFAULT_CONFIG["max_gap"], test.first_frame)
        scores = evaluate_sequence(test.gt_table, MotTable.from_arrays(*rows), TEST).summary()
        loop_mota.append(scores["MOTA"])
    loop_timed_s = time.perf_counter() - start
    loop_s = loop_compile_s + loop_timed_s * num_configs / len(timed)

    mota = result.scores["MOTA"].reshape(2, len(CLUTTER_RATES), len(BIRTH_RATES))
    best = [np.unravel_index(np.argmax(m), m.shape) for m in mota]
    print(
        json.dumps(
            {
                "benchmark": "sweep_speed",
                "sequence": test.info.name,
                "train_frames": list(TRAIN),
                "test_frames": list(TEST),
                "grid": "9 lambda_r (0.1..10) x 9 lambda_s (0.02..2), log-spaced; UM + GM",
                "tracker_runs": num_configs,
                "num_particles": DEFAULT_CONFIG["num_particles"],
                "births_per_detection": DEFAULT_CONFIG["births_per_detection"],
                "devices": len(jax.devices()),
                "chunk_size": args.chunk_size,
                "sweep_s": sweep_s,
                "loop_s": loop_s,
                "loop_compile_s": loop_compile_s,
                "loop_run_and_score_s_per_config": loop_timed_s / len(timed),
                "loop_configs_timed": len(timed),
                "loop_extrapolated": len(timed) < num_configs,
                "ratio_loop_over_sweep": loop_s / sweep_s,
                "goal_sweep_under_120_s": sweep_s < 120,
                "goal_ratio_at_least_5": loop_s / sweep_s >= 5,
                # Batched and unbatched XLA programs round differently (float32); over 398
                # frames the discrete decisions (resampling, assignment) can then diverge.
                "loop_vs_sweep_max_abs_mota_diff_pct": float(
                    100 * np.max(np.abs(np.asarray(loop_mota) - result.scores["MOTA"][timed]))
                ),
                "best_mota": {
                    variant: {
                        "MOTA_pct": float(100 * mota[v][best[v]]),
                        "lambda_r": float(CLUTTER_RATES[best[v][0]]),
                        "lambda_s": float(BIRTH_RATES[best[v][1]]),
                    }
                    for v, variant in enumerate(("UM", "GM"))
                },
                "cpu_count": os.cpu_count(),
                "platform": platform.platform(),
                "jax_version": jax.__version__,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
