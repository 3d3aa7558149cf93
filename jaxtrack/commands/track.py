"""``jaxtrack track``: run the particle PHD tracker on MOTChallenge sequences.

One sequence:  ``jaxtrack track SEQ_DIR --out RES.txt [--frames A:B] [--config FILE]``
All sequences: ``jaxtrack track --benchmark MOT_ROOT --out RES_DIR`` (one ``<SEQ>.txt`` each)

The default configuration (uniform birth and clutter intensities, see
``jaxtrack.filters.phd_defaults.default_phd_params``) is the same for every sequence; image
size and frame rate come from each ``seqinfo.ini``. ``--config FILE.json`` overrides it with
the keys ``num_particles``, ``births_per_detection``, ``extraction`` ("partition" or "gmm"),
``birth_rate`` and ``clutter_rate``. The configuration used is written beside the results as
``<RES>.config.json``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from jaxtrack.errors import FileFormatError, InputError

#: The documented default configuration (one for all sequences).
DEFAULT_CONFIG = {
    "num_particles": 2048,
    "births_per_detection": 32,
    "extraction": "partition",
    "birth_rate": 0.2,
    "clutter_rate": 1.0,
}


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "track",
        help="run the particle PHD tracker on a sequence folder (or a benchmark root)",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("sequence", nargs="?", metavar="SEQ_DIR", help="MOTChallenge sequence")
    parser.add_argument("--benchmark", metavar="MOT_ROOT", help="folder of sequence folders")
    parser.add_argument(
        "--out", required=True, help="result file (RES.txt), or a folder with --benchmark"
    )
    parser.add_argument("--frames", metavar="A:B", help="only frames A..B (1-based, inclusive)")
    parser.add_argument("--config", metavar="FILE", help="JSON file overriding the defaults")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    parser.set_defaults(func=run)


def load_config(path: str | None) -> dict:
    """The default configuration updated by the JSON file at ``path`` (if any).

    Raises:
        FileFormatError: the file is missing, not a JSON object, or has an unknown key or a
            value of the wrong type.
    """
    config = dict(DEFAULT_CONFIG)
    if path is None:
        return config
    file = Path(path)
    if not file.is_file():
        raise FileFormatError(file, None, "file not found")
    try:
        overrides = json.loads(file.read_text())
    except json.JSONDecodeError as err:
        raise FileFormatError(file, err.lineno, f"not valid JSON ({err.msg})") from None
    if not isinstance(overrides, dict):
        raise FileFormatError(file, None, "must hold a JSON object")
    for key, value in overrides.items():
        if key not in DEFAULT_CONFIG:
            raise FileFormatError(
                file, None, f"unknown key {key!r}; known: {', '.join(DEFAULT_CONFIG)}"
            )
        expected = type(DEFAULT_CONFIG[key])
        if expected is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, expected) or isinstance(value, bool):
            raise FileFormatError(file, None, f"{key} must be a {expected.__name__}, got {value!r}")
        config[key] = value
    if config["extraction"] not in ("partition", "gmm"):
        raise FileFormatError(file, None, "extraction must be 'partition' or 'gmm'")
    for key in ("num_particles", "births_per_detection", "birth_rate", "clutter_rate"):
        if config[key] <= 0:
            raise FileFormatError(file, None, f"{key} must be positive, got {config[key]}")
    return config


def track_sequence(sequence_dir, out_path, config: dict, seed: int = 0, frames=None) -> int:
    """Tracks one sequence folder and writes MOTChallenge results; returns the row count."""
    import jax

    from jaxtrack.association.offline import track_rows
    from jaxtrack.filters.base import run as run_filter
    from jaxtrack.filters.phd import phd_filter
    from jaxtrack.filters.phd_defaults import default_phd_params
    from jaxtrack.io import load_sequence, write_results

    seq = load_sequence(sequence_dir, frames=frames)
    params = default_phd_params(
        seq.info.im_width,
        seq.info.im_height,
        seq.info.frame_rate,
        birth_rate=config["birth_rate"],
        clutter_rate=config["clutter_rate"],
    )
    filt = phd_filter(
        config["num_particles"],
        births_per_detection=config["births_per_detection"],
        extraction=config["extraction"],
    )
    _, info = run_filter(filt, jax.random.PRNGKey(seed), params, seq.detections)
    rows = track_rows(info.tracks, seq.first_frame)
    write_results(out_path, rows.frames, rows.ids, rows.boxes, rows.scores)
    used = {**config, "seed": seed, "sequence": str(sequence_dir)}
    used["frames"] = [seq.first_frame, seq.last_frame]
    Path(f"{Path(out_path).with_suffix('')}.config.json").write_text(json.dumps(used, indent=2))
    return len(rows.frames)


def run(args) -> int:
    from tqdm import tqdm

    if (args.sequence is None) == (args.benchmark is None):
        raise InputError("give either SEQ_DIR or --benchmark MOT_ROOT (not both)")
    config = load_config(args.config)
    if args.sequence is not None:
        start = time.perf_counter()
        count = track_sequence(args.sequence, args.out, config, args.seed, args.frames)
        print(f"wrote {args.out} ({count} boxes, {time.perf_counter() - start:.1f} s)")
        return 0
    if args.frames is not None:
        raise InputError("--frames applies to one sequence, not to --benchmark")
    root = Path(args.benchmark)
    sequences = (
        sorted(p for p in root.iterdir() if (p / "seqinfo.ini").is_file()) if root.is_dir() else []
    )
    if not sequences:
        raise InputError(f"{root}: no sequence folders (with seqinfo.ini) found")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for seq_dir in tqdm(sequences, desc="tracking", unit="seq"):
        track_sequence(seq_dir, out / f"{seq_dir.name}.txt", config, args.seed)
    print(f"wrote {len(sequences)} result files to {out}")
    return 0
