"""What every experiment shares: data, splits, scores and the files written.

**Data.** An experiment runs on one MOTChallenge sequence folder, by default the synthetic
scene of :mod:`jaxtrack.datasets.synthetic` generated from the experiment's seed and written
into the output folder (:func:`synthetic_sequence`); ``quick=True`` gives a short scene
(:data:`QUICK_SCENE`) for seconds-long smoke runs.

**Protocol** (PHD-context Sec. V): context is learned on a training span and the trackers are
scored on the disjoint rest. :func:`split_halves` takes the first half of the frames for
training and the second half for testing (``n // 2`` and ``n - n // 2`` frames).

**Scores** (:func:`score_summary`): CLEAR MOT / TrackEval MOTA and MOTP, the VACE detection
scores MODA and MODP (pooled over frames, :mod:`jaxtrack.metrics.vace`), IDF1 and HOTA, in
percent, plus the FP, FN and ID-switch counts, all at IoU 0.5 with MOT15's rules.

**Files.** Each experiment writes a CSV table (:func:`write_csv`), a PNG figure and a
short markdown summary (:func:`markdown_table`) into its output folder
(:func:`output_folder`).
"""

from __future__ import annotations

import csv
import math
import platform
import subprocess
from collections.abc import Callable, Iterable, Sequence
from importlib import metadata
from pathlib import Path
from typing import NamedTuple

import cv2

from jaxtrack.configs import SMOOTHINGS, TrackerConfig
from jaxtrack.context.samples import WARMUP_FRAMES
from jaxtrack.datasets.scene_config import SceneConfig
from jaxtrack.datasets.synthetic import generate_scene, write_scene
from jaxtrack.errors import InputError
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.io import MotSequence, MotTable, load_sequence
from jaxtrack.io.motchallenge import read_seqinfo
from jaxtrack.limits import Rule
from jaxtrack.metrics.errors import FN_KINDS, FP_KINDS, classify_errors
from jaxtrack.metrics.evaluate import Evaluation, evaluate_sequence
from jaxtrack.metrics.switches import SCORE_NAMES
from jaxtrack.pipelines.context import learn_context
from jaxtrack.plot.scene import save_scene_preview

#: Scores reported in percent, in this order.
SCORE_KEYS = ("MOTA", "MOTP", "MODA", "MODP", "IDF1", "HOTA")
#: Error counts reported beside the scores.
COUNT_KEYS = ("FP", "FN", "IDSW")
#: The identity switches of each kind (:mod:`jaxtrack.metrics.switches`), as row keys.
SWITCH_KEYS = tuple(SCORE_NAMES.values())
#: Row keys of the misses and false positives by kind (:mod:`jaxtrack.metrics.errors`).
ERROR_KEYS = (*(f"FN_{kind}" for kind in FN_KINDS), *(f"FP_{kind}" for kind in FP_KINDS))
#: The short synthetic scene of ``--quick`` runs: 120 frames, a short burn-in (fewer targets
#: in view, so fast runs) and more births than the default scene, so that a 60-frame
#: training half still holds birth events.
QUICK_SCENE = SceneConfig(num_frames=120, burn_in_frames=40, birth_rate=0.15)
#: Tracker configuration overrides of ``--quick`` runs (few particles).
QUICK_TRACKER_CONFIG = PHDConfig(num_particles=256, births_per_detection=8)
#: The shortest training span: the birth events' warm-up plus as many frames again.
MIN_TRAIN_FRAMES = 2 * WARMUP_FRAMES


class Split(NamedTuple):
    """A sequence cut into a training span and a disjoint test span.

    Attributes:
        train: the training span (context is learned here).
        test: the test span (trackers are scored here).
    """

    train: MotSequence
    test: MotSequence


def output_folder(path: str | Path) -> Path:
    """Creates (if needed) and returns an experiment's output folder.

    Raises:
        InputError: ``path`` exists and is not a folder.
    """
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise InputError(f"{folder}: exists and is not a folder")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def synthetic_sequence(out_dir: str | Path, seed: int, quick: bool = False) -> Path:
    """Generates the synthetic scene of ``seed`` and writes it as a MOTChallenge folder.

    Args:
        out_dir: the sequence folder to write (created if needed).
        seed: the scene's seed (>= 0).
        quick: the short :data:`QUICK_SCENE` instead of the default 800-frame scene.

    Returns:
        The sequence folder.

    Raises:
        InputError: a negative seed.
    """

    if seed < 0:
        raise InputError(f"seed must be >= 0, got {seed}")
    scene = generate_scene(seed, QUICK_SCENE if quick else None)
    out = write_scene(scene, out_dir)
    save_scene_preview(scene, out / "preview.png")
    return out


def split_halves(sequence_dir: str | Path) -> Split:
    """Loads a sequence folder as a training first half and a test second half.

    Args:
        sequence_dir: a MOTChallenge sequence folder with ground truth.

    Returns:
        The :class:`Split`: frames ``1..n//2`` and ``n//2+1..n``.

    Raises:
        InputError: no ground truth (the test span is scored against it), or a sequence too
            short to learn from half of it.
        FileFormatError: a missing or malformed file.
    """
    folder = Path(sequence_dir)
    if not folder.is_dir():
        raise InputError(f"{folder}: sequence folder not found")
    info = read_seqinfo(folder / "seqinfo.ini")
    half = info.seq_length // 2
    if half < MIN_TRAIN_FRAMES:
        raise InputError(
            f"{folder}: {info.seq_length} frames; a half needs at least {MIN_TRAIN_FRAMES}"
        )
    train = load_sequence(folder, frames=(1, half))
    _ground_truth(train)
    return Split(train=train, test=load_sequence(folder, frames=(half + 1, info.seq_length)))


def learn_split(
    split: Split,
    config: PHDConfig,
    seed: int = 0,
    birth_from: str = "tracks",
    progress: Callable[[str], None] | None = None,
    first_frame: bool = False,
):
    """Learns context on ``split.train`` as the experiments do: clutter from the ground truth.

    Args:
        split: the training and test spans.
        config: the tracker configuration (also the configuration of the
            UM run that yields the birth events).
        seed: seeds the tracker run and the order in which samples are learned.
        birth_from: ``"tracks"`` (a UM tracker run, the paper's source) or ``"gt"``.
        progress: called with a short description before each long step.
        first_frame: also learn the first frame's intensity (GM, A1, A4 and A6 then start
            from it).

    Returns:
        The :class:`~jaxtrack.context.learn.LearnedContext`.

    Raises:
        InputError: no birth or clutter events on the training span.
    """

    return learn_context(
        split.train,
        birth_from=birth_from,
        clutter_from="gt",
        seed=seed,
        tracker_config=config,
        first_frame=first_frame,
        progress=progress,
    )


#: The repository this package runs from when it is a git checkout (an editable install).
REPOSITORY = Path(__file__).resolve().parents[2]
#: The distributions whose versions :func:`environment` records: the particle runs depend on
#: their float32 rounding, so a table is reproducible only with the same versions.
ENVIRONMENT_PACKAGES = ("jax", "jaxlib", "numpy", "scipy", "optax")


def environment() -> dict[str, str | None]:
    """What produced an experiment's numbers: the jaxtrack commit (``git describe``-like
    short hash, with ``+changes`` when the checkout differs from it; None outside a git
    checkout), Python, OpenCV and :data:`ENVIRONMENT_PACKAGES` (None where not installed).
    Written into the experiments' records so that a table that does not reproduce can be
    traced to a code or an environment change."""
    found: dict[str, str | None] = {"jaxtrack_commit": checkout_commit(REPOSITORY)}
    found["python"] = platform.python_version()
    for name in ENVIRONMENT_PACKAGES:
        try:
            found[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            found[name] = None
    found["opencv"] = cv2.__version__
    return found


def environment_line(found: dict[str, str | None]) -> str:
    """:func:`environment` as one sentence for a ``table.md`` / ``summary.md``."""
    versions = ", ".join(f"{k} {v}" for k, v in found.items() if k != "jaxtrack_commit")
    return f"Environment: jaxtrack commit {found.get('jaxtrack_commit') or 'unknown'}; {versions}."


def environment_lines(record: dict) -> list[str]:
    """The ``table.md`` lines stating ``record["environment"]`` (none for a record
    without one)."""
    found = record.get("environment")
    return [environment_line(found)] if found else []


def checkout_commit(root: Path) -> str | None:
    """The short hash of the git checkout at ``root`` (``+changes`` when a tracked file
    differs from it); None when ``root`` is not a git checkout or git cannot tell."""
    if not (root / ".git").exists():
        return None
    try:
        head = _git(root, "rev-parse", "--short=12", "HEAD")
        changes = _git(root, "status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return None
    return f"{head}+changes" if changes else head


def _git(root: Path, *args: str) -> str:
    """``git -C root ARGS``'s standard output, stripped (raises on failure)."""
    done = subprocess.run(
        ["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10, check=True
    )
    return done.stdout.strip()


#: The video experiments' ``--smoothing``: each configuration's own default (the Fusion
#: tracker's offline output smoothed since session 63, the others' not), or one of
#: :data:`~jaxtrack.configs.SMOOTHINGS` for every tracker.
EXPERIMENT_SMOOTHINGS = ("default", *SMOOTHINGS)
#: Its rule.
EXPERIMENT_SMOOTHING = Rule(
    "every compared tracker's smoothing: 'default' (each configuration's own), 'none' or "
    "'rts' (all of them)",
    str,
    choices=EXPERIMENT_SMOOTHINGS,
)


def smoothed_trackers(
    trackers: dict[str, TrackerConfig], smoothing: str
) -> dict[str, TrackerConfig]:
    """Every configuration of ``trackers`` with its ``smoothing`` setting set to
    ``smoothing`` (``"default"``: returned unchanged), in the same order.

    Raises:
        InputError: an unknown smoothing.
    """
    EXPERIMENT_SMOOTHING.check("smoothing", smoothing)
    if smoothing == "default":
        return dict(trackers)
    return {name: config.replace(smoothing=smoothing) for name, config in trackers.items()}


def smoothed_names(trackers: dict[str, TrackerConfig]) -> list[str]:
    """The names of the configurations whose offline output is smoothed, in order (a
    record's ``smoothed``)."""
    return [name for name, config in trackers.items() if config.smoothing != "none"]


def smoothing_sentence(record: dict) -> str:
    """The sentence a ``table.md`` states its trackers' smoothing with: every tracker's
    (``smoothing`` "rts"), those named in ``smoothed`` (their configurations' default), or
    empty when none is smoothed (the trackers' own estimates)."""
    if record.get("smoothing") == "rts":
        return (
            "Every tracker's output smoothed (`smoothing: rts`, "
            "`jaxtrack.association.smoothing`): not the papers' protocol, which scores the "
            "filters' own estimates. "
        )
    smoothed = record.get("smoothed", [])
    if not smoothed:
        return ""
    return (
        f"Smoothed by their configuration's default (`smoothing: rts`, "
        f"`jaxtrack.association.smoothing`; beyond the paper): {', '.join(smoothed)}; the "
        "other trackers output their own estimates. "
    )


def evaluate_rows(
    sequence: MotSequence, rows: MotTable, frames: tuple[int, int] | None = None
) -> Evaluation:
    """Scores a tracker's rows against a sequence span's ground truth.

    Args:
        sequence: the span tracked, with its ground truth.
        rows: the tracker's rows on it.
        frames: a part ``(first, last)`` of the span (1-based, inclusive) scored alone: the
            ground truth and the rows cut to it first, as ``jaxtrack eval --frames`` does
            (default: the whole span).

    Raises:
        InputError: the sequence has no ground truth.
    """
    gt = _ground_truth(sequence)
    if frames is None:
        return evaluate_sequence(gt, rows, frames=(sequence.first_frame, sequence.last_frame))
    return evaluate_sequence(gt.frame_span(*frames), rows.frame_span(*frames), frames=frames)


def _ground_truth(sequence: MotSequence) -> MotTable:
    """The sequence span's ground truth.

    Raises:
        InputError: the sequence has no ground truth.
    """
    if sequence.gt_table is None:
        raise InputError(f"{sequence.path}: no ground truth (gt/gt.txt) to score against")
    return sequence.gt_table


def score_summary(evaluation: Evaluation) -> dict[str, float | int]:
    """The :data:`SCORE_KEYS` in percent (rounded to 0.01) and the :data:`COUNT_KEYS`."""
    summary = evaluation.summary()
    scores: dict[str, float | int] = {key: round(100 * summary[key], 2) for key in SCORE_KEYS}
    scores.update({key: int(summary[key]) for key in COUNT_KEYS})
    return scores


def switch_counts(evaluation: Evaluation) -> dict[str, int]:
    """The :data:`SWITCH_KEYS` of an evaluation (they add up to its ``IDSW``)."""
    return {key: int(evaluation.switches.get(kind, 0)) for kind, key in SCORE_NAMES.items()}


def error_counts(
    sequence: MotSequence,
    rows: MotTable,
    detections: MotTable | None = None,
    frames: tuple[int, int] | None = None,
) -> dict[str, int]:
    """The :data:`ERROR_KEYS` of a tracker's rows on a sequence span, against the detections
    it was given; they add up to its ``FN`` and ``FP`` (as :func:`evaluate_rows` counts them).

    Args:
        sequence: the span tracked, with its ground truth.
        rows: the tracker's rows on it.
        detections: the detections the tracker was given (default: ``sequence.det_table``,
            the sequence's own).
        frames: a part ``(first, last)`` of the span scored alone (default: the whole span);
            the ground truth, rows and detections are cut to it first.
    """
    gt = _ground_truth(sequence)
    if detections is None:
        detections = sequence.det_table
    span = (sequence.first_frame, sequence.last_frame) if frames is None else frames
    counts = classify_errors(
        gt.frame_span(*span),
        rows.frame_span(*span),
        detections.frame_span(*span),
        span,
    ).counts()
    return {f"{side}_{kind}": n for side, kinds in counts.items() for kind, n in kinds.items()}


def summed_errors(counts: Iterable[dict[str, int]]) -> dict[str, int]:
    """The :data:`ERROR_KEYS` of a pooled row: the sum of its sequences' counts."""
    counts = list(counts)
    return {key: sum(count[key] for count in counts) for key in ERROR_KEYS}


#: What the error kinds of :data:`ERROR_KEYS` mean, for the experiments' ``table.md``.
ERROR_KINDS_TEXT = (
    "What the detections offered in each error's frame (`jaxtrack eval --errors`, "
    "`jaxtrack.metrics.errors`; overlap = IoU >= 0.3): misses not detected (no detection "
    "overlaps the object), detection misplaced (one overlaps, none well), output "
    "misplaced (well detected, an unmatched output box overlaps it), dropped (well "
    "detected, no output box there); false positives misplaced (on a missed object), "
    "duplicate (on a matched one), clutter (on a detection mapped to no object), "
    "phantom (on nothing)."
)


def error_section(rows: Sequence[dict], labels: Sequence[str], pooled: Sequence[str]) -> list[str]:
    """``table.md`` lines on the misses and false positives by kind, for the rows whose
    ``sequence`` is one of ``pooled`` (every row when none is); no lines when no row has
    the kinds (records written before they existed)."""
    shown = _pooled_rows(rows, pooled, ERROR_KEYS[0])
    return shown and [
        "## Misses and false positives by kind\n",
        f"{ERROR_KINDS_TEXT} Each side adds up to the row's FN or FP.\n",
        markdown_table(shown, (*labels, *ERROR_KEYS)),
    ]


def switch_section(
    rows: Sequence[dict], labels: Sequence[str], pooled: Sequence[str], total: str = "IDSW"
) -> list[str]:
    """``table.md`` lines: a heading, what the kinds mean, and a table (the ``labels``
    columns, ``total`` and the :data:`SWITCH_KEYS`) of the rows whose ``sequence`` is one of
    ``pooled`` (every row when none is: a quick run). Rows without the kinds (records written
    before they existed) are left out; no lines when no row is left."""
    shown = _pooled_rows(rows, pooled, SWITCH_KEYS[0])
    return shown and [
        "## Identity switches by kind\n",
        "What each switch's two tracks did (`jaxtrack eval --switches`, "
        "`jaxtrack.metrics.switches`): exchange = the tracks traded objects, drift = the old "
        "track moved on to another object, takeover = the new track came from another object, "
        "lost = the old track ended, replaced = the old track stayed on no object.\n",
        markdown_table(shown, (*labels, total, *SWITCH_KEYS)),
    ]


def _pooled_rows(rows: Sequence[dict], pooled: Sequence[str], key: str) -> list[dict]:
    """The rows whose ``sequence`` is one of ``pooled`` (every row when none is: a quick
    run) that hold ``key``."""
    shown = [row for row in rows if row["sequence"] in pooled] or list(rows)
    return [row for row in shown if key in row]


def percent_difference(value: float, reference: float) -> float:
    """``100 (value - reference) / |reference|``: a score's change relative to a baseline.

    The denominator is the magnitude of the reference, so that an improvement is positive
    also when the reference is negative (a MOTA below 0). NaN when the reference is 0.
    """
    if reference == 0:
        return math.nan
    return 100.0 * (value - reference) / abs(reference)


def write_csv(path: str | Path, rows: Sequence[dict], columns: Sequence[str]) -> Path:
    """Writes ``rows`` (dicts holding every column) as a CSV file with a header line."""
    path = Path(path)
    with path.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(columns), extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    return path


def markdown_table(rows: Sequence[dict], columns: Sequence[str]) -> str:
    """A markdown table of ``rows``: floats with one decimal, NaN as ``n/a``."""

    def cell(value) -> str:
        if isinstance(value, float):
            if math.isnan(value):
                return "n/a"
            return f"{value:.1f}"
        return str(value)

    lines = [
        "| " + " | ".join(columns) + " |",
        "|" + "|".join("---" for _ in columns) + "|",
    ]
    lines += ["| " + " | ".join(cell(row[column]) for column in columns) + " |" for row in rows]
    return "\n".join(lines) + "\n"
