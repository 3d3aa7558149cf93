"""CMT's ablation (Cui et al., Sec. VII, Table II): MTb, MTb+CPD and CMT against PHD and Kalman.

**Sequences** (:func:`experiment_sequences`). The three MOT15 sequences with video:
PETS09-S2L1 (its frames are ``video/vtest.avi`` of the shared data), TUD-Campus and
TUD-Stadtmitte (``<name>.mp4`` in their folders), with their MOT15 detections, whole; and
the scripted video scenes (:mod:`jaxtrack.datasets.video_scene`: crossings of similarly
dressed people, groups, an occluder) of the seeds :data:`HELD_OUT_SEEDS`, which no default
of the toolkit was tuned on, written to ``OUT/scenes/video-SEED``, with their simulated
detections.

**Trackers** (:func:`experiment_trackers`), all on the same detections (CMT's foreground
blobs): the three CMT variants (``--variant mtb|cpd|cmt``: bootstrap proposal + EWOM,
contextual proposal + EWOM, contextual proposal + COM), the PHD tracker and the Kalman
data-association baseline, each with its default configuration and the experiment's seed.
Trackers that look at the images run with the frames streamed
(:func:`~jaxtrack.pipelines.stream.track_streamed`), the others through
:func:`~jaxtrack.pipelines.tracking.track_sequences`.

**Scores** (:func:`score_row`): CMT's error rates OE, DE, SE (:mod:`jaxtrack.metrics.cmt`)
and MOTA, IDF1, HOTA, IDSW, MT, Frag at IoU 0.5 with MOT15's rules, per sequence, and pooled
(:func:`~jaxtrack.metrics.evaluate.combine_sequences`, TrackEval's combination) over the
three MOT15 sequences and over the synthetic scenes. The off-the-shelf peers of the issue
are quoted (:data:`PEERS`), not re-run. :func:`goal_checks` tests the issue's goals.

**Seeds.** The trackers run with ``tracker_seeds`` consecutive seeds from ``seed`` (each
seed its own zones, learned from its own PHD run); the table and the goals read the mean
over the seeds of each (sequence or pooled group, tracker) row (:func:`seed_mean_rows`),
``table.md`` and ``results.json`` also list every seed's pooled rows, and the result files,
Fig. 8 and the zones described are the first seed's.

**Zones.** CMT's entry/exit zones (its exits, and the contextual proposal's zone distance)
are learned on the fly on each tracked span, as ``jaxtrack track --tracker cmt`` does without
``--zones`` (:func:`~jaxtrack.pipelines.zones.tracker_zones`: from the PHD tracker's
trajectories on the same detections, no ground truth read), once per sequence for the three
variants; a run's rows are those ``jaxtrack track`` writes with the same configuration and
seed.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from tqdm import tqdm

from jaxtrack.configs import TrackerConfig
from jaxtrack.context.zones import SceneZones
from jaxtrack.datasets.video_config import VideoSceneConfig
from jaxtrack.datasets.video_files import write_video_scene
from jaxtrack.datasets.video_scene import generate_video_scene
from jaxtrack.errors import InputError
from jaxtrack.experiments.cmt_analysis import (
    FIG8_FRAMES,
    discrimination_analysis,
    prediction_analysis,
    scene_crossings,
)
from jaxtrack.experiments.common import (
    ERROR_KEYS,
    QUICK_TRACKER_CONFIG,
    SWITCH_KEYS,
    environment,
    environment_lines,
    error_counts,
    error_section,
    evaluate_rows,
    markdown_table,
    output_folder,
    smoothed_names,
    smoothed_trackers,
    smoothing_sentence,
    summed_errors,
    switch_counts,
    switch_section,
)
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.filters.kalman_tracker import KalmanConfig
from jaxtrack.filters.phd_tracker import PHDConfig
from jaxtrack.filters.registry import build_tracker, tracker_entry
from jaxtrack.io import MotSequence, load_sequence, write_mot_file
from jaxtrack.io.video import open_sequence_frames
from jaxtrack.metrics.cmt import DEFAULT_TOLERANCE as CROSSING_TOLERANCE
from jaxtrack.metrics.cmt import crossing_swap_fields, crossing_swap_rate
from jaxtrack.metrics.evaluate import Evaluation, combine_sequences, switch_table
from jaxtrack.pipelines.stream import track_streamed
from jaxtrack.pipelines.tracking import track_sequences, tracker_description
from jaxtrack.pipelines.zones import tracker_zones
from jaxtrack.plot.cmt_analysis import save_discrimination_figure, save_prediction_figure
from jaxtrack.types import MotTable

#: The MOT15 sequences with video, in table order.
VIDEO_SEQUENCES = ("PETS09-S2L1", "TUD-Campus", "TUD-Stadtmitte")
#: PETS09-S2L1's frames, relative to the shared data folder (the sequence folder has none).
PETS_VIDEO = Path("video") / "vtest.avi"
#: Seeds of the synthetic video scenes: held out, never used to tune any default.
HELD_OUT_SEEDS = (101, 102, 103)
#: The CMT variants, table name -> ``CMTConfig.variant``.
CMT_VARIANTS = {"MTb": "mtb", "MTb+CPD": "cpd", "CMT": "cmt"}
#: Name of the pooled rows over the MOT15 sequences and over the synthetic scenes.
MOT15_COMBINED = "MOT15 video combined"
SYNTHETIC_COMBINED = "synthetic combined"
#: Both pooled rows.
POOLED = (MOT15_COMBINED, SYNTHETIC_COMBINED)
#: Scores in percent, then counts, as the table shows them.
PERCENT_KEYS = ("OE", "DE", "SE", "MOTA", "IDF1", "HOTA")
COUNT_KEYS = ("IDSW", "MT", "Frag")
#: The columns of the result table.
TABLE_COLUMNS = ("sequence", "tracker", *PERCENT_KEYS, *COUNT_KEYS)
#: SE on the scripted crossings (%) and its counts, in the synthetic scenes' rows
#: (:func:`~jaxtrack.metrics.cmt.crossing_swap_fields`).
CROSSING_KEYS = ("SE_crossings", "crossing_frames", "crossing_swap_frames")
#: The columns of ``table.md``'s crossing section.
CROSSING_COLUMNS = ("sequence", "tracker", "SE", *CROSSING_KEYS)
#: Runs of every (sequence, tracker) by default, trackers' seeds ``--seed`` onwards: one run of
#: a particle tracker is not a measurement (CMT's pooled MOT15 IDF1 was 60.6 / 61.2 / 55.5
#: with seeds 0 / 1 / 2, and the SE goal passed on seeds 0 and 2 only). The table and the
#: goals read the means (:func:`seed_mean_rows`).
TRACKER_SEEDS = 3
#: Quick runs: the first frames of TUD-Campus and of one short synthetic scene.
QUICK_FRAMES = 24
#: The synthetic scene of quick runs (the shortest the script allows; TUD-Campus's size, so
#: that both sequences share one compile per tracker).
QUICK_SCENE = VideoSceneConfig(num_frames=240)
#: Off-the-shelf peers on the same MOT15 detections, quoted from issue 17 (TrackEval 1.3.0,
#: MOT15 mode, pooled over the three MOT15 sequences; not re-run here).
PEERS = (
    ("SORT (`trackers` 2.6.1)", 59.7, 47.5, 38.0, 19, 119, 380, "40.2 / 99"),
    ("ByteTrack (`trackers` 2.6.1)", 60.8, 51.8, 39.5, 19, 98, 377, "45.4 / 79"),
    ("OC-SORT (`trackers` 2.6.1)", 58.6, 52.2, 39.6, 14, 85, 347, "45.9 / 68"),
    ("norfair 2.3.0 (no ReID)", 62.3, 58.6, 42.8, 25, 47, 175, "55.8 / 35"),
    ("norfair 2.3.0 + HSV-histogram ReID", 62.4, 41.6, 34.9, 23, 46, 178, "34.5 / 36"),
    ("deep-sort-realtime 1.3.2 + HSV histogram", 62.0, 45.9, 36.9, 23, 114, 234, "39.8 / 100"),
    ("OpenCV CSRT (+ IoU association)", 57.2, 50.1, 39.3, 24, 101, 359, "44.4 / 81 (5 fps)"),
    ("jaxtrack PHD (this repo, default)", 68.4, 52.3, 41.5, 24, 61, 175, "46.5 / 50"),
)
#: The columns of :data:`PEERS`.
PEER_COLUMNS = ("tracker", "MOTA", "IDF1", "HOTA", "MT", "IDSW", "Frag", "PETS09 IDF1 / IDSW")
#: The goal's bar: the off-the-shelf peers' best combined IDF1 (norfair, 58.6) and fewest
#: identity switches (norfair + ReID, 46); this repository's PHD row is not a peer.
BEST_PEER_IDF1 = max(peer[2] for peer in PEERS[:-1])
BEST_PEER_IDSW = min(peer[5] for peer in PEERS[:-1])


class ExperimentSequence(NamedTuple):
    """A sequence of the experiment.

    Attributes:
        name: its name in the table.
        folder: the MOTChallenge folder (``seqinfo.ini``, ``det/``, ``gt/``).
        video: its frames when the folder has none of its own (PETS09-S2L1), else None.
        frames: the 1-based inclusive span tracked and scored (None: every frame).
        synthetic: a scripted video scene (else a MOT15 sequence).
    """

    name: str
    folder: Path
    video: Path | None
    frames: tuple[int, int] | None
    synthetic: bool


def experiment_trackers(quick: bool = False) -> dict[str, TrackerConfig]:
    """The compared trackers, table name -> configuration (defaults; ``quick``: few
    particles, for smoke runs whose numbers mean nothing)."""
    cmt = CMTConfig()
    phd = PHDConfig()
    if quick:
        cmt = cmt.replace(max_components=8, particles_per_component=16)
        phd = QUICK_TRACKER_CONFIG
    trackers: dict[str, TrackerConfig] = {
        name: cmt.replace(variant=variant) for name, variant in CMT_VARIANTS.items()
    }
    trackers["PHD"] = phd
    trackers["Kalman"] = KalmanConfig()
    return trackers


class ExperimentStart(NamedTuple):
    """What :func:`start_experiment` prepared.

    Attributes:
        start: ``time.perf_counter()`` when the experiment started.
        out: the output folder (created).
        steps: ``print`` when the experiment reports its steps, else None.
        sequences: :func:`experiment_sequences` (synthetic scenes written to ``out/scenes``).
    """

    start: float
    out: Path
    steps: Callable[[str], None] | None
    sequences: list[ExperimentSequence]


def start_experiment(
    out_dir: str | Path, data: str | Path, seeds: Sequence[int], quick: bool, progress: bool
) -> ExperimentStart:
    """The common start of the video-tracker experiments (CMT ablation, Hierarchical, Fusion).

    Checks the seeds, starts the clock, creates ``out_dir`` and loads / writes
    :func:`experiment_sequences` into ``out_dir/scenes``.

    Raises:
        InputError: no seeds, or data missing from ``data``.
    """
    if not seeds:
        raise InputError("at least one synthetic scene seed is needed")
    start = time.perf_counter()
    out = output_folder(out_dir)
    steps = print if progress else None
    sequences = experiment_sequences(Path(data), out / "scenes", seeds, quick, steps)
    return ExperimentStart(start, out, steps, sequences)


def experiment_sequences(
    data: Path,
    scenes: Path,
    seeds: Sequence[int],
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
) -> list[ExperimentSequence]:
    """The MOT15 video sequences of ``data`` and the synthetic scenes of ``seeds``.

    The synthetic scenes are generated and written (video included) to
    ``scenes/video-SEED``. ``quick``: TUD-Campus and the first seed's short scene
    (:data:`QUICK_SCENE`), their first :data:`QUICK_FRAMES` frames.

    Raises:
        InputError: a MOT15 sequence or PETS09-S2L1's video missing from ``data``.
    """
    names = ("TUD-Campus",) if quick else VIDEO_SEQUENCES
    frames = (1, QUICK_FRAMES) if quick else None
    sequences = []
    for name in names:
        folder = data / "mot15" / name
        if not (folder / "seqinfo.ini").is_file():
            raise InputError(f"{folder}: MOT15 sequence not found (is --data the shared data?)")
        video = data / PETS_VIDEO if name == "PETS09-S2L1" else None
        if video is not None and not video.is_file():
            raise InputError(f"{video}: PETS09-S2L1's video not found")
        sequences.append(ExperimentSequence(name, folder, video, frames, False))
    for seed in seeds[:1] if quick else seeds:
        scene = generate_video_scene(seed, QUICK_SCENE if quick else None)
        if progress is not None:
            progress(f"rendering the synthetic scene {scene.info.name}")
        folder = write_video_scene(scene, scenes / scene.info.name)
        sequences.append(ExperimentSequence(scene.info.name, folder, None, frames, True))
    return sequences


def track_sequence(
    sequence: ExperimentSequence,
    loaded: MotSequence,
    config: TrackerConfig,
    seed: int,
    zones: SceneZones | None = None,
) -> MotTable:
    """A tracker's result rows on a sequence, as ``jaxtrack track`` makes them: streamed
    frames for a tracker that uses them, detections alone for the others; ``zones`` for a
    tracker that takes them (:func:`~jaxtrack.pipelines.zones.tracker_zones`)."""
    entry = tracker_entry(config.tracker)
    _, params = build_tracker(config, loaded.info, zones if entry.takes_zones else None)
    if not entry.uses_frames:
        return track_sequences([loaded], config, seed, [params])[0]
    with open_sequence_frames(sequence.folder, loaded.info, sequence.video) as reader:
        return track_streamed(loaded, reader, config, seed, params)


def score_row(
    sequence: str,
    tracker: str,
    synthetic: bool,
    evaluation: Evaluation,
    crossings: dict[str, int] | None = None,
    errors: dict[str, int] | None = None,
) -> dict[str, Any]:
    """One table row: :data:`PERCENT_KEYS` in percent (rounded to 0.01), :data:`COUNT_KEYS`,
    and whether the sequence (or group) is synthetic; with ``crossings``
    (:func:`~jaxtrack.metrics.cmt.crossing_swap_fields` or their sums), also
    :data:`CROSSING_KEYS`; with ``errors`` (:func:`~jaxtrack.experiments.common.error_counts`
    or their sums), also :data:`~jaxtrack.experiments.common.ERROR_KEYS`."""
    summary = evaluation.summary()
    row: dict[str, Any] = {"sequence": sequence, "tracker": tracker, "synthetic": synthetic}
    row.update({key: round(100 * summary[key], 2) for key in PERCENT_KEYS})
    row.update({key: int(summary[key]) for key in COUNT_KEYS})
    row.update(switch_counts(evaluation))
    if crossings is not None:
        row["SE_crossings"] = round(100 * crossing_swap_rate(crossings), 2)
        row.update({key: int(crossings[key]) for key in CROSSING_KEYS[1:]})
    if errors is not None:
        row.update({key: int(errors[key]) for key in ERROR_KEYS})
    return row


def crossing_counts(
    sequence: MotSequence,
    rows: MotTable,
    crossings: Sequence[tuple[Sequence[int], tuple[int, int]]],
) -> dict[str, int]:
    """:func:`~jaxtrack.metrics.cmt.crossing_swap_fields` of a tracker's rows on a synthetic
    scene's span, from the switches of the evaluation's matching and the scene's scripted
    crossings (:func:`~jaxtrack.experiments.cmt_analysis.scene_crossings`)."""
    span = (sequence.first_frame, sequence.last_frame)
    switches = switch_table(sequence.gt_table, rows, span)
    return crossing_swap_fields(switches.frame, switches.gt_id, crossings, span, CROSSING_TOLERANCE)


class AblationResult(NamedTuple):
    """What :func:`ablation_table` measured.

    Attributes:
        rows: per sequence then pooled, one row per tracker (:data:`TABLE_COLUMNS`).
        results: ``{sequence: {tracker: result rows}}``.
        seconds: ``{tracker: seconds}`` of tracking over all sequences (compiles included).
        zones: ``{sequence: the zones CMT used}`` (None: no zones).
        zone_notes: ``{sequence: the zones CMT used, in words}``.
    """

    rows: list[dict[str, Any]]
    results: dict[str, dict[str, MotTable]]
    seconds: dict[str, float]
    zones: dict[str, SceneZones | None]
    zone_notes: dict[str, str]


def ablation_table(
    sequences: Sequence[ExperimentSequence],
    trackers: dict[str, TrackerConfig],
    seed: int = 0,
    progress: bool = False,
) -> AblationResult:
    """Tracks and scores every sequence with every tracker, and pools the scores.

    Args:
        sequences: the sequences (:func:`experiment_sequences`).
        trackers: table name -> configuration (:func:`experiment_trackers`).
        seed: the trackers' seed.
        progress: a progress bar over the (sequence, tracker) runs.

    Returns:
        The :class:`AblationResult`; pooled rows (:data:`MOT15_COMBINED`,
        :data:`SYNTHETIC_COMBINED`) follow the per-sequence rows of each group of two or
        more sequences.
    """
    runs = [(sequence, name) for sequence in sequences for name in trackers]
    bar = tqdm(runs, desc="tracking", unit="run", disable=not progress)
    loaded: dict[str, MotSequence] = {}
    zones: dict[str, SceneZones | None] = {}
    notes: dict[str, str] = {}
    evaluations: dict[tuple[str, str], Evaluation] = {}
    scripted: dict[str, list] = {}
    crossings: dict[tuple[str, str], dict[str, int]] = {}
    errors: dict[tuple[str, str], dict[str, int]] = {}
    results: dict[str, dict[str, MotTable]] = {}
    seconds = dict.fromkeys(trackers, 0.0)
    for sequence, name in bar:
        bar.set_postfix_str(f"{sequence.name} {name}")
        if sequence.name not in loaded:
            loaded[sequence.name] = load_sequence(sequence.folder, sequence.frames)
            if sequence.synthetic:
                scripted[sequence.name] = scene_crossings(sequence.folder)
            zones[sequence.name], notes[sequence.name] = tracker_zones(
                loaded[sequence.name], None, seed
            )
        start = time.perf_counter()
        rows = track_sequence(
            sequence, loaded[sequence.name], trackers[name], seed, zones[sequence.name]
        )
        seconds[name] += time.perf_counter() - start
        results.setdefault(sequence.name, {})[name] = rows
        evaluations[sequence.name, name] = evaluate_rows(loaded[sequence.name], rows)
        errors[sequence.name, name] = error_counts(loaded[sequence.name], rows)
        if sequence.synthetic:
            crossings[sequence.name, name] = crossing_counts(
                loaded[sequence.name], rows, scripted[sequence.name]
            )
    table = []
    for synthetic, combined in ((False, MOT15_COMBINED), (True, SYNTHETIC_COMBINED)):
        group = [sequence.name for sequence in sequences if sequence.synthetic == synthetic]
        for sequence_name in group:
            for name in trackers:
                table.append(
                    score_row(
                        sequence_name,
                        name,
                        synthetic,
                        evaluations[sequence_name, name],
                        crossings.get((sequence_name, name)),
                        errors[sequence_name, name],
                    )
                )
        if len(group) > 1:
            for name in trackers:
                pooled = combine_sequences(evaluations[s, name] for s in group)
                summed = None
                if synthetic:
                    summed = {
                        key: sum(crossings[s, name][key] for s in group)
                        for key in CROSSING_KEYS[1:]
                    }
                kinds = summed_errors(errors[s, name] for s in group)
                table.append(score_row(combined, name, synthetic, pooled, summed, kinds))
    return AblationResult(table, results, seconds, zones, notes)


def goal_checks(rows: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Issue 17's goals on the table rows (those whose rows are present).

    * per sequence (MOT15 and synthetic): OE falls MTb -> MTb+CPD -> CMT, and CMT's OE is at
      most 1/3 of MTb's;
    * on the pooled synthetic scenes (or the one scene): SE on the scripted crossings of
      similarly dressed people (``SE_crossings``, the issue's wording) falls from MTb+CPD to
      CMT (COM), the whole scenes' SE shown beside it;
    * pooled over the three MOT15 sequences: CMT's IDF1 above :data:`BEST_PEER_IDF1` and
      its IDSW below :data:`BEST_PEER_IDSW`;
    * on the pooled synthetic scenes: CMT's IDF1 above PHD's and its IDSW below.

    Returns:
        ``{"goal", "value", "met"}`` per check (``value`` a sentence with the numbers).
    """
    by = {(row["sequence"], row["tracker"]): row for row in rows}
    sequences = list(dict.fromkeys(row["sequence"] for row in rows))
    checks = []
    for sequence in sequences:
        if sequence in POOLED:
            continue
        if not all((sequence, name) in by for name in CMT_VARIANTS):
            continue
        oe = [by[sequence, name]["OE"] for name in CMT_VARIANTS]
        checks.append(
            {
                "goal": f"{sequence}: OE falls MTb -> MTb+CPD -> CMT",
                "value": "OE " + " -> ".join(f"{value:.2f}%" for value in oe),
                "met": oe[0] > oe[1] > oe[2],
            }
        )
        checks.append(
            {
                "goal": f"{sequence}: CMT's OE at most 1/3 of MTb's",
                "value": f"{oe[2]:.2f}% vs {oe[0]:.2f}% / 3 = {oe[0] / 3:.2f}%",
                "met": oe[2] <= oe[0] / 3,
            }
        )
    synthetic = _group_row_name(rows, SYNTHETIC_COMBINED)
    if synthetic is not None and (synthetic, "CMT") in by:
        cpd, cmt = by[synthetic, "MTb+CPD"], by[synthetic, "CMT"]
        if "SE_crossings" in cmt:
            checks.append(
                {
                    "goal": f"{synthetic}: SE on the scripted crossings falls with COM "
                    "(MTb+CPD -> CMT)",
                    "value": f"SE on the crossings {cpd['SE_crossings']:.2f}% -> "
                    f"{cmt['SE_crossings']:.2f}% ({cpd['crossing_swap_frames']} -> "
                    f"{cmt['crossing_swap_frames']} of {cmt['crossing_frames']} frames); "
                    f"whole scenes {cpd['SE']:.2f}% -> {cmt['SE']:.2f}%",
                    "met": cmt["SE_crossings"] < cpd["SE_crossings"],
                }
            )
        if (synthetic, "PHD") in by:
            phd = by[synthetic, "PHD"]
            checks.append(
                {
                    "goal": f"{synthetic}: CMT's IDF1 above PHD's and IDSW below",
                    "value": f"IDF1 {cmt['IDF1']:.1f} vs {phd['IDF1']:.1f}, "
                    f"IDSW {cmt['IDSW']} vs {phd['IDSW']}",
                    "met": cmt["IDF1"] > phd["IDF1"] and cmt["IDSW"] < phd["IDSW"],
                }
            )
    if (MOT15_COMBINED, "CMT") in by:
        cmt = by[MOT15_COMBINED, "CMT"]
        checks.append(
            {
                "goal": f"{MOT15_COMBINED}: CMT's IDF1 above the best peer's and IDSW below",
                "value": f"IDF1 {cmt['IDF1']:.1f} vs {BEST_PEER_IDF1}, "
                f"IDSW {cmt['IDSW']} vs {BEST_PEER_IDSW}",
                "met": cmt["IDF1"] > BEST_PEER_IDF1 and cmt["IDSW"] < BEST_PEER_IDSW,
            }
        )
    return checks


def _group_row_name(rows: Sequence[dict[str, Any]], combined: str) -> str | None:
    """The synthetic group's pooled row name, or its only sequence's name, or None."""
    names = list(dict.fromkeys(row["sequence"] for row in rows if row["synthetic"]))
    if combined in names:
        return combined
    return names[0] if len(names) == 1 else None


def seed_mean_rows(rows_by_seed: Sequence[Sequence[dict[str, Any]]]) -> list[dict[str, Any]]:
    """The rows of several seeds' tables averaged per (sequence, tracker).

    Every seed's table has the same rows in the same order (:func:`ablation_table`); each
    score is the mean over the seeds, rounded to 0.01 (counts too: a mean of 58, 62 and 57
    identity switches is 59.0).

    Raises:
        ValueError: no tables, or tables whose rows differ.
    """
    if not rows_by_seed:
        raise ValueError("no tables to average")
    first = rows_by_seed[0]
    keys = [(row["sequence"], row["tracker"]) for row in first]
    for rows in rows_by_seed[1:]:
        if [(row["sequence"], row["tracker"]) for row in rows] != keys:
            raise ValueError("the seeds' tables have different rows")
    means = []
    for index, row in enumerate(first):
        mean = {k: row[k] for k in ("sequence", "tracker", "synthetic")}
        counts = (*COUNT_KEYS, *SWITCH_KEYS, *CROSSING_KEYS[1:], *ERROR_KEYS)
        for key in (*PERCENT_KEYS, *COUNT_KEYS, *SWITCH_KEYS, *CROSSING_KEYS, *ERROR_KEYS):
            if key not in row:
                continue
            values = [rows[index][key] for rows in rows_by_seed]
            mean[key] = round(float(np.mean(values)), 2)
            if len(rows_by_seed) == 1 and key in counts:
                mean[key] = int(values[0])
        means.append(mean)
    return means


def pooled_rows_by_seed(
    seeds: Sequence[int], rows_by_seed: Sequence[Sequence[dict[str, Any]]]
) -> list[dict[str, Any]]:
    """Every seed's pooled rows (:data:`MOT15_COMBINED`, :data:`SYNTHETIC_COMBINED`; every
    sequence's rows when a table has no pooled row, e.g. a quick run) of the CMT variants and
    PHD, with a ``seed`` column (:data:`SEED_COLUMNS`)."""
    kept = []
    for seed, rows in zip(seeds, rows_by_seed, strict=True):
        has_pooled = any(row["sequence"] in POOLED for row in rows)
        kept += [
            {"seed": seed, **row}
            for row in rows
            if (row["sequence"] in POOLED or not has_pooled)
            and row["tracker"] in (*CMT_VARIANTS, "PHD")
        ]
    return kept


#: The columns of :func:`pooled_rows_by_seed`'s table.
SEED_COLUMNS = ("seed", *TABLE_COLUMNS)


def write_results(out: Path, results: dict[str, dict[str, MotTable]]) -> list[Path]:
    """Writes each tracker's rows as ``out/sequences/SEQUENCE/TRACKER.txt`` (MOTChallenge)."""
    files = []
    for sequence, by_tracker in results.items():
        for name, rows in by_tracker.items():
            path = out / "sequences" / sequence / f"{name.replace('+', '-')}.txt"
            path.parent.mkdir(parents=True, exist_ok=True)
            write_mot_file(path, rows)
            files.append(path)
    return files


#: Fig. 8's comparisons (:func:`~jaxtrack.experiments.cmt_analysis.prediction_analysis`)
#: and their titles.
FIG8_PANELS = {
    "same_particles": "same particles, proposed one frame ahead",
    "tracker_runs": "each tracker run's own proposals",
}
#: The files the experiment writes into its output folder (besides ``sequences/`` and
#: ``scenes/``).
ABLATION_FILES = ("table.md", "results.json", "fig8_prediction.png", "fig9_discrimination.png")


class CMTAblation(NamedTuple):
    """The experiment's outcome.

    Attributes:
        rows: the table rows (:func:`ablation_table`).
        goals: the goal checks (:func:`goal_checks`).
        files: the files written.
    """

    rows: list[dict[str, Any]]
    goals: list[dict[str, Any]]
    files: list[Path]


def peer_rows() -> list[dict[str, Any]]:
    """:data:`PEERS` as table rows (:data:`PEER_COLUMNS`)."""
    return [dict(zip(PEER_COLUMNS, peer, strict=True)) for peer in PEERS]


def goal_lines(goals: Sequence[dict[str, Any]]) -> list[str]:
    """One line per goal check: ``PASS|FAIL goal: value``."""
    return [f"{'PASS' if g['met'] else 'FAIL'} {g['goal']}: {g['value']}" for g in goals]


def run_cmt_ablation(
    out_dir: str | Path,
    data: str | Path,
    seeds: Sequence[int] = HELD_OUT_SEEDS,
    seed: int = 0,
    quick: bool = False,
    progress: bool = True,
    tracker_seeds: int = 1,
    smoothing: str = "default",
) -> CMTAblation:
    """The whole experiment (module docstring): the table, the goals and both figures.

    Args:
        out_dir: the output folder (created if needed).
        data: the shared data folder (``mot15/``, ``video/vtest.avi``).
        seeds: seeds of the synthetic video scenes (quick: the first only).
        seed: the trackers' first seed.
        tracker_seeds: runs of every tracker on every sequence, seeds ``seed ..
            seed + tracker_seeds - 1`` (>= 1); the table and the goals read their means.
        quick: a smoke run (:func:`experiment_sequences`, :func:`experiment_trackers`).
        progress: print each step and show a progress bar over the runs.
        smoothing: every tracker's ``smoothing`` setting (``"default"``: each
            configuration's own; ``"none"``: the trackers' own estimates; ``"rts"``:
            :mod:`jaxtrack.association.smoothing`); the scores read
            the smoothed rows, Fig. 8 and 9 (inside the trackers) do not change.

    Returns:
        The :class:`CMTAblation`.

    Raises:
        InputError: no seeds, data missing from ``data``, or an unknown smoothing.
    """
    if tracker_seeds < 1:
        raise InputError(f"tracker_seeds must be at least 1, got {tracker_seeds}")
    trackers = smoothed_trackers(experiment_trackers(quick), smoothing)
    start, out, steps, sequences = start_experiment(out_dir, data, seeds, quick, progress)
    run_seeds = list(range(seed, seed + tracker_seeds))
    by_seed = []
    for run_seed in run_seeds:
        if steps is not None and tracker_seeds > 1:
            steps(f"trackers' seed {run_seed} ({run_seed - seed + 1} of {tracker_seeds})")
        by_seed.append(ablation_table(sequences, trackers, run_seed, progress))
    result = by_seed[0]
    rows = seed_mean_rows([r.rows for r in by_seed])
    goals = goal_checks(rows)
    if steps is not None:
        steps("Fig. 8: proposed particles of MTb and MTb+CPD")
    real = next(s for s in sequences if not s.synthetic)
    fig8 = prediction_analysis(
        real.folder,
        real.video,
        real.frames if quick else FIG8_FRAMES,
        trackers["MTb"],
        trackers["MTb+CPD"],
        seed,
        result.zones[real.name],
        result.zone_notes[real.name],
    )
    if steps is not None:
        steps("Fig. 9: COM and EWOM on the crossing pair")
    fig9 = discrimination_analysis(next(s.folder for s in sequences if s.synthetic), quick)
    files = write_results(out, result.results)
    fig8_path = save_prediction_figure(
        out / "fig8_prediction.png",
        np.asarray(fig8["frames"]),
        {
            FIG8_PANELS[name]: {k: np.asarray(v, float) for k, v in fig8[name]["distances"].items()}
            for name in FIG8_PANELS
        },
        f"Fig. 8: prediction precision on {fig8['sequence']}",
    )
    fig9_path = save_discrimination_figure(
        out / "fig9_discrimination.png",
        np.asarray(fig9["frames"]),
        {"COM": np.asarray(fig9["COM"]), "EWOM": np.asarray(fig9["EWOM"])},
        f"Fig. 9: targets {fig9['ids'][0]} (A) and {fig9['ids'][1]} (B) of {fig9['sequence']}",
    )
    seconds = round(time.perf_counter() - start, 1)
    record = {
        "quick": quick,
        "seed": seed,
        "smoothing": smoothing,
        "smoothed": smoothed_names(trackers),
        "tracker_seeds": run_seeds,
        "synthetic_seeds_held_out": list(seeds[:1] if quick else seeds),
        "sequences": [
            {
                "name": s.name,
                "folder": str(s.folder),
                "video": None if s.video is None else str(s.video),
                "frames": s.frames,
                "synthetic": s.synthetic,
                "zones": result.zone_notes[s.name],
            }
            for s in sequences
        ],
        "trackers": {name: tracker_description(config) for name, config in trackers.items()},
        "rows": rows,
        "rows_by_seed": {str(s): r.rows for s, r in zip(run_seeds, by_seed, strict=True)},
        "goals": goals,
        "peers": peer_rows(),
        "tracking_seconds": {
            k: round(sum(r.seconds[k] for r in by_seed), 1) for k in result.seconds
        },
        "fig8": fig8,
        "fig9": fig9,
        "seconds": seconds,
        "environment": environment(),
    }
    json_path = out / "results.json"
    json_path.write_text(json.dumps(record, indent=1) + "\n")
    table_path = out / "table.md"
    table_path.write_text(table_markdown(record))
    return CMTAblation(rows, goals, [table_path, json_path, fig8_path, fig9_path, *files])


def table_markdown(record: dict[str, Any]) -> str:
    """``table.md``: the scores, the quoted peers, the goals, both analyses, the setting."""
    fig8, fig9 = record["fig8"], record["fig9"]
    seeds = ", ".join(map(str, record["synthetic_seeds_held_out"]))
    lines = [
        "# CMT ablation (Cui et al., Sec. VII)\n",
        f"{'Quick smoke run (numbers mean nothing). ' if record['quick'] else ''}"
        f"{smoothing_sentence(record)}"
        f"{_seeds_sentence(record['tracker_seeds'])}; synthetic video scenes of seeds {seeds} "
        "(held out: never used to tune any default). Scores in %, IoU 0.5, MOT15 rules; "
        "OE/DE/SE as `jaxtrack.metrics.cmt` defines them; pooled rows combine the sequences "
        "as TrackEval does.\n",
        markdown_table(record["rows"], TABLE_COLUMNS),
        *switch_section(record["rows"], ("sequence", "tracker"), POOLED),
        *error_section(record["rows"], ("sequence", "tracker"), POOLED),
        *_crossing_section(record["rows"]),
        *_seed_section(record),
        "## Off-the-shelf peers (quoted from issue 17, not re-run)\n",
        "Same MOT15 detections, TrackEval 1.3.0 MOT15 mode, pooled over PETS09-S2L1 + "
        "TUD-Campus + TUD-Stadtmitte.\n",
        markdown_table(record["peers"], PEER_COLUMNS),
        "## Goals\n",
        *(f"- {line}" for line in goal_lines(record["goals"])),
        "",
        f"## Fig. 8: prediction precision ({fig8['sequence']}, frames "
        f"{fig8['frames'][0]}-{fig8['frames'][-1]})\n",
        "Summed distance of a tracked target's proposed particles to its ground-truth centre "
        "(mean over the tracked targets), on the frames where both proposals track a target "
        "(`jaxtrack.experiments.cmt_analysis`).\n",
        *(_fig8_line(FIG8_PANELS[name], fig8[name]) for name in FIG8_PANELS),
        "",
        f"## Fig. 9: discriminative power ({fig9['sequence']}, targets {fig9['ids'][0]} and "
        f"{fig9['ids'][1]}, crossing frames {fig9['crossing_frames'][0]}-"
        f"{fig9['crossing_frames'][1]})\n",
        f"Mean likelihood difference A - B: COM {_cell(fig9['mean']['COM'])}, EWOM "
        f"{_cell(fig9['mean']['EWOM'])}; COM above EWOM on "
        f"{_percent(fig9['com_above_ewom_fraction'])} of {len(fig9['frames'])} frames; "
        f"negative (A's model prefers B) on {fig9['negative_frames']['COM']} (COM) and "
        f"{fig9['negative_frames']['EWOM']} (EWOM) frames.\n",
        "## Setting\n",
        *(f"- {s['name']}: {s['zones']}" for s in record["sequences"]),
        "",
        "Tracking time (s, compiles included): "
        + ", ".join(f"{k} {v}" for k, v in record["tracking_seconds"].items())
        + f"; whole run {record['seconds']} s.\n",
        *environment_lines(record),
    ]
    return "\n".join(lines)


def _crossing_section(rows: Sequence[dict[str, Any]]) -> list[str]:
    """SE on the scripted crossings, the synthetic rows of the CMT variants (none without)."""
    kept = [row for row in rows if "SE_crossings" in row and row["tracker"] in CMT_VARIANTS]
    if not kept:
        return []
    return [
        "## SE on the scripted crossings\n",
        f"Frames from a crossing's first to {CROSSING_TOLERANCE} frames after its last, and "
        "those in which one of its people has an identity switch "
        "(`jaxtrack.metrics.cmt.crossing_swap_fields`); SE is the whole scene's.\n",
        markdown_table(kept, CROSSING_COLUMNS),
    ]


def _seeds_sentence(tracker_seeds: Sequence[int]) -> str:
    if len(tracker_seeds) == 1:
        return f"Trackers' seed {tracker_seeds[0]}"
    return (
        f"Mean over the trackers' seeds {tracker_seeds[0]}-{tracker_seeds[-1]} "
        f"({len(tracker_seeds)} runs of every tracker on every sequence; the goals read these "
        "means; the result files, Fig. 8 and the zones are seed "
        f"{tracker_seeds[0]}'s)"
    )


def _seed_section(record: dict[str, Any]) -> list[str]:
    """The pooled rows seed by seed (none for a single seed)."""
    seeds = record["tracker_seeds"]
    if len(seeds) == 1:
        return []
    rows = pooled_rows_by_seed(seeds, [record["rows_by_seed"][str(s)] for s in seeds])
    return [
        "## Seed by seed\n",
        "What the means above average: every seed's pooled rows (every row without pooled "
        "ones), CMT variants and PHD.\n",
        markdown_table(rows, SEED_COLUMNS),
    ]


def _fig8_line(title: str, comparison: dict[str, Any]) -> str:
    prior, cpd = comparison["mean"].values()
    return (
        f"- {title}: Gaussian prior {_cell(prior)} px, contextual proposal {_cell(cpd)} px; "
        f"CPD below the prior on {_percent(comparison['cpd_below_prior_fraction'])} of "
        f"{comparison['frames_compared']} frames."
    )


def _cell(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.0f}%"
