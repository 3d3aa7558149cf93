"""``jaxtrack demo``: learn context, track with UM and GM, sweep magnitudes, write figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from jaxtrack.commands.arguments import add_out, add_quiet, add_seed
from jaxtrack.commands.paths import SCENE_FILES, check_outputs, output_folder
from jaxtrack.experiments.demo import run_demo

DESCRIPTION = """\
The toolkit's main job in one command, on the embedded synthetic surveillance scene (the
scene of --seed, 800 frames, generated on the fly, true context known):

  1. learn the birth and clutter intensities on frames 1:400 (recursive MAP-EM mixtures;
     births from a tracker run, clutter from the ground truth);
  2. track frames 401:800 with uniform intensities (UM) and with the learned ones (GM) and
     score both (MOTA, MOTP, MODA, MODP, IDF1, HOTA);
  3. sweep the clutter and birth magnitudes over a 5 x 5 log-spaced grid for UM and GM in
     one vmapped call;
  4. print a results table and write into --out:
       demo.png            learned intensities and MOTA against both magnitudes
       intensities.png     learned vs true intensities (+ birth/clutter_evolution.png)
       sweep.png           MOTA/MOTP/MODA/MODP against lambda_r and lambda_s
       sweep_mota.png      MOTA over the whole grid, UM and GM
       tracks.png          particles, estimates and tracks over a test frame
       results.csv, sweep.csv, UM.txt, GM.txt (MOTChallenge results), summary.md
       scene/              the synthetic sequence (MOTChallenge folder)

About 2-3 minutes on 2 CPU cores (most of it compiling and learning)."""

#: The files the demo writes into --out (the scene's in scene/).
DEMO_FILES = (
    "demo.png",
    "intensities.png",
    "birth_evolution.png",
    "clutter_evolution.png",
    "sweep.png",
    "sweep_mota.png",
    "tracks.png",
    "results.csv",
    "sweep.csv",
    "UM.txt",
    "GM.txt",
    "summary.md",
    *(f"scene/{name}" for name in SCENE_FILES),
)

EPILOG = """\
examples:
  jaxtrack demo
  jaxtrack demo --out /tmp/demo --seed 3
  jaxtrack demo --quick          # seconds-long smoke run (short scene, 2 x 2 grid)"""


def register(subparsers) -> None:
    """Adds the ``demo`` parser to the CLI's sub-parsers."""
    parser = subparsers.add_parser(
        "demo",
        help="learn context, track with UM and GM, sweep magnitudes, write figures",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_out(
        parser,
        "output folder (default: ./jaxtrack-demo; created if needed)",
        required=False,
        metavar="DIR",
        default="jaxtrack-demo",
    )
    add_seed(parser)
    parser.add_argument(
        "--quick", action="store_true", help="seconds-long smoke run (short scene, few particles)"
    )
    add_quiet(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Runs the demo; prints each step, the results table and the files written."""

    start = time.perf_counter()

    def step(text: str) -> None:
        print(f"[{time.perf_counter() - start:5.0f} s] {text}", flush=True)

    out = Path(args.out)
    check_outputs(output_folder("--out", args.out, DEMO_FILES), [])
    result = run_demo(out, args.seed, args.quick, progress=None if args.quiet else step)
    if not args.quiet:
        print()
    print(result.files[-1].read_text())
    print(f"wrote {len(result.files)} files into {out}/ (figure: {out}/demo.png)")
    return 0
