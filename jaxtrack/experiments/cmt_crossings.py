"""COM against EWOM on the scripted crossings, by how alike the pair are dressed (issue 17's
SE goal, CMT paper Sec. VI and Fig. 9).

The scripted video scene's crossing (:mod:`jaxtrack.datasets.video_script`) brings two
similarly dressed people through the same point. How alike they are is
:attr:`~jaxtrack.datasets.video_config.VideoSceneConfig.crossing_alike`, one *family* of
scenes per value:

* ``both`` (the generator's default, the scenes of ``cmt-ablation``): top and bottom the same
  palette colour within +-4 levels, below the video's own noise: no feature of the pool
  separates them, so no observation model can;
* ``top`` / ``bottom``: that half alike, the other half a different palette colour: similarly
  dressed with one separating feature, the case the contextual observation model is built for
  (its weights follow the features that separate the targets in the field of context).

For each family and scene seed the scene is written to ``OUT/scenes/FAMILY-SEED`` and tracked
by MTb+CPD (equally weighted features, EWOM) and CMT (the same proposal with COM), default
configurations, zones learned on the fly, ``tracker_seeds`` tracker seeds. Measured per
family, over its scenes:

* SE on the crossings: frames with an identity switch of one of the pair, from the crossing's
  first frame to :data:`~jaxtrack.metrics.cmt.DEFAULT_TOLERANCE` frames after its last
  (:func:`~jaxtrack.metrics.cmt.crossing_swap_fields`), summed over scenes and tracker seeds;
* the pair's identities across the crossing (:func:`~jaxtrack.metrics.reassociation.
  identity_cases`: kept, switched, lost), summed likewise;
* IDSW, IDF1 and MOTA of the whole scenes, pooled over the family (TrackEval's combination),
  means over the tracker seeds;
* Fig. 9's likelihood gap between the two people under COM and EWOM
  (:func:`~jaxtrack.experiments.cmt_analysis.discrimination_analysis`, no tracker), its mean
  over each scene's frames, then over the scenes.

The goal line per family: SE on the crossings falls with COM (CMT's crossing swap frames
below MTb+CPD's). No default of the trackers was set on any scene this experiment draws.
"""

from __future__ import annotations

import dataclasses
import json
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from jaxtrack.datasets import VideoSceneConfig, generate_video_scene
from jaxtrack.datasets.video_config import CROSSING_ALIKE
from jaxtrack.datasets.video_files import write_video_scene
from jaxtrack.errors import InputError
from jaxtrack.experiments.cmt_ablation import (
    SYNTHETIC_COMBINED,
    ExperimentSequence,
    ablation_table,
    experiment_trackers,
    goal_lines,
    write_results,
)
from jaxtrack.experiments.cmt_analysis import discrimination_analysis
from jaxtrack.experiments.common import (
    environment,
    environment_lines,
    markdown_table,
    output_folder,
)
from jaxtrack.filters.cmt_tracker import CMTConfig
from jaxtrack.io import load_sequence
from jaxtrack.metrics.reassociation import identity_cases
from jaxtrack.plot.cmt_analysis import save_crossing_families_figure

#: The scene families (values of ``crossing_alike``), in the table's order.
FAMILIES = CROSSING_ALIKE
#: Scene seeds of every family by default: fresh when this experiment was written (session
#: 56); no default of any tracker was set on them.
DEFAULT_SEEDS = tuple(range(222, 234))
#: A quick run's scene: shorter than the default, long enough for the scripted events of most
#: seeds (cmt-ablation's 240-frame quick scene is too short for most of :data:`DEFAULT_SEEDS`).
QUICK_SCENE = VideoSceneConfig(num_frames=360)
#: The compared CMT variants: the observation model is the only difference.
VARIANTS = ("MTb+CPD", "CMT")
#: The files written into the output folder (besides ``scenes/`` and ``sequences/``, the first
#: tracker seed's result files ``sequences/FAMILY-SEED/TRACKER.txt``).
FILES = ("table.md", "results.json", "crossings.png")
#: The table's columns.
COLUMNS = (
    "family",
    "tracker",
    "SE_crossings",
    "crossing_swap_frames",
    "crossing_frames",
    "kept",
    "switched",
    "lost",
    "IDSW",
    "IDF1",
    "MOTA",
)
#: Outcomes of the pair's identity cases that the table counts.
OUTCOMES = ("kept", "switched", "lost")


class CrossingFamilies(NamedTuple):
    """What :func:`run_crossing_families` measured.

    Attributes:
        rows: one row per family and variant (:data:`COLUMNS`).
        goals: one per family (``goal``, ``value``, ``met``).
        gaps: per family, Fig. 9's mean likelihood gap ``{"COM", "EWOM", "COM_above"}``.
        files: the files written.
    """

    rows: list[dict[str, Any]]
    goals: list[dict[str, Any]]
    gaps: dict[str, dict[str, float]]
    files: list[Path]


def family_sequences(
    out: Path, family: str, seeds: Sequence[int], quick: bool = False
) -> list[tuple[ExperimentSequence, list]]:
    """The scenes of one family (``crossing_alike``), written to ``out/FAMILY-SEED`` and named
    so, each with its scripted events; quick: the shorter :data:`QUICK_SCENE`, whole.

    Raises:
        InputError: an unknown family.
    """
    if family not in FAMILIES:
        raise InputError(f"unknown family {family!r}: one of {', '.join(FAMILIES)}")
    base = QUICK_SCENE if quick else VideoSceneConfig()
    config = dataclasses.replace(base, crossing_alike=family)
    scenes = []
    for seed in seeds:
        name = f"{family}-{seed}"
        scene = generate_video_scene(seed, config)
        folder = write_video_scene(scene, out / name)
        scenes.append((ExperimentSequence(name, folder, None, None, True), scene.events))
    return scenes


def crossing_outcomes(gt, rows, scripted) -> dict[str, int]:
    """The crossing pair's identity outcomes (:data:`OUTCOMES` and ``unscored``) of one run
    (``gt``: the scene's ground truth)."""
    cases = identity_cases(rows, gt, [e for e in scripted if e.kind == "crossing"])
    return {o: sum(c["outcome"] == o for c in cases) for o in (*OUTCOMES, "unscored")}


def _pooled_row(rows: Sequence[dict[str, Any]], name: str, scenes: int) -> dict[str, Any]:
    """A variant's row over the family's scenes (the pooled row, or the one scene's)."""
    wanted = [r for r in rows if r["tracker"] == name]
    if scenes > 1:
        wanted = [r for r in wanted if r["sequence"] == SYNTHETIC_COMBINED]
    (row,) = wanted
    return row


def run_crossing_families(
    out_dir: str | Path,
    seeds: Sequence[int] = DEFAULT_SEEDS,
    families: Sequence[str] = FAMILIES,
    seed: int = 0,
    tracker_seeds: int = 3,
    quick: bool = False,
    progress: bool = True,
    config: CMTConfig | None = None,
) -> CrossingFamilies:
    """The whole experiment (module docstring); writes :data:`FILES` into ``out_dir``.

    Args:
        out_dir: the output folder (created if needed; scenes in ``scenes/``).
        seeds: scene seeds, the same for every family (quick: the first only).
        families: values of ``crossing_alike`` (:data:`FAMILIES`).
        seed: the trackers' first seed.
        tracker_seeds: runs per scene and variant, seeds ``seed ..`` (>= 1).
        quick: a smoke run (one short scene per family, few particles; numbers mean nothing).
        progress: print each step and show a progress bar over the runs.
        config: the CMT configuration both variants start from (:func:`variant_configs`);
            None: the defaults.

    Raises:
        InputError: no seeds or families, an unknown family, ``tracker_seeds`` < 1, or a
            ``config`` that sets the variant.
    """
    if not seeds or not families:
        raise InputError("at least one scene seed and one family are needed")
    unknown = [family for family in families if family not in FAMILIES]
    if unknown:
        raise InputError(f"unknown families {unknown}: each one of {', '.join(FAMILIES)}")
    if tracker_seeds < 1:
        raise InputError(f"tracker_seeds must be at least 1, got {tracker_seeds}")
    trackers = variant_configs(config, quick)
    start = time.perf_counter()
    out = output_folder(out_dir)
    steps: Callable[[str], None] | None = print if progress else None
    seeds = list(seeds[:1] if quick else seeds)
    run_seeds = list(range(seed, seed + tracker_seeds))
    rows, goals, gaps, scenes_record = [], [], {}, {}
    files: list[Path] = []
    for family in families:
        if steps is not None:
            steps(f"family {family}: writing {len(seeds)} scenes")
        written = family_sequences(out / "scenes", family, seeds, quick)
        sequences = [sequence for sequence, _ in written]
        scripted = {sequence.name: events for sequence, events in written}
        truth = {s.name: load_sequence(s.folder).gt_table for s in sequences}
        analyses = [discrimination_analysis(s.folder, quick) for s in sequences]
        gaps[family] = {
            "COM": float(np.mean([a["mean"]["COM"] for a in analyses])),
            "EWOM": float(np.mean([a["mean"]["EWOM"] for a in analyses])),
            "COM_above": float(np.mean([a["com_above_ewom_fraction"] for a in analyses])),
        }
        totals = {name: _empty_totals() for name in trackers}
        per_scene: dict[str, dict[str, dict[str, int]]] = {}
        for run_seed in run_seeds:
            if steps is not None:
                steps(f"family {family}: trackers' seed {run_seed}")
            result = ablation_table(sequences, trackers, run_seed, progress)
            if run_seed == seed:
                files += write_results(out, result.results)
            for name in trackers:
                row = _pooled_row(result.rows, name, len(sequences))
                total = totals[name]
                for key in ("IDSW", "IDF1", "MOTA"):
                    total[key] += row[key] / tracker_seeds
                for key in ("crossing_swap_frames", "crossing_frames"):
                    total[key] += row[key]
                for s in sequences:
                    outcome = crossing_outcomes(
                        truth[s.name], result.results[s.name][name], scripted[s.name]
                    )
                    scene = per_scene.setdefault(s.name, {}).setdefault(name, _empty_cases())
                    for key, count in outcome.items():
                        total[key] += count
                        scene[key] += count
                    scene_row = next(
                        r for r in result.rows if r["sequence"] == s.name and r["tracker"] == name
                    )
                    scene["crossing_swap_frames"] += scene_row["crossing_swap_frames"]
        for name, total in totals.items():
            rate = 100 * total["crossing_swap_frames"] / max(1, total["crossing_frames"])
            rows.append(
                {
                    "family": family,
                    "tracker": name,
                    "SE_crossings": round(rate, 2),
                    **{k: round(v, 2) if isinstance(v, float) else v for k, v in total.items()},
                }
            )
        goals.append(
            family_goal(family, totals["MTb+CPD"], totals["CMT"], len(seeds), tracker_seeds)
        )
        scenes_record[family] = {
            "scenes": [s.name for s in sequences],
            "fig9_means": {s.name: a["mean"] for s, a in zip(sequences, analyses, strict=True)},
            "per_scene": per_scene,
        }
    figure = save_crossing_families_figure(out / "crossings.png", rows, gaps)
    record = {
        "quick": quick,
        "scene_seeds": seeds,
        "tracker_seeds": run_seeds,
        "families": list(families),
        "config": trackers["CMT"].overrides(),
        "rows": rows,
        "goals": goals,
        "fig9_gap": gaps,
        "scenes": scenes_record,
        "seconds": round(time.perf_counter() - start, 1),
        "environment": environment(),
    }
    json_path = out / "results.json"
    json_path.write_text(json.dumps(record, indent=1) + "\n")
    table_path = out / "table.md"
    table_path.write_text(table_markdown(record))
    return CrossingFamilies(rows, goals, gaps, [table_path, json_path, figure, *files])


def variant_configs(config: CMTConfig | None = None, quick: bool = False) -> dict[str, CMTConfig]:
    """:data:`VARIANTS` -> configuration: ``config`` (default: CMT's defaults) with the
    variant set (quick: fewer slots and particles, as in ``cmt-ablation --quick``).

    Raises:
        InputError: ``config`` sets the variant (this experiment compares two).
    """
    base = CMTConfig() if config is None else config
    if "variant" in base.overrides():
        raise InputError(
            f"the configuration sets variant {base.variant!r}; cmt-crossings runs both "
            f"{' and '.join(VARIANTS)}: leave the variant out"
        )
    defaults = experiment_trackers(quick)
    sizes = ("max_components", "particles_per_component") if quick else ()
    return {
        name: base.replace(
            variant=defaults[name].variant, **{key: getattr(defaults[name], key) for key in sizes}
        )
        for name in VARIANTS
    }


def family_goal(
    family: str, ewom: dict[str, Any], com: dict[str, Any], scenes: int, tracker_seeds: int
) -> dict[str, Any]:
    """The goal line of a family: SE on the crossings falls with COM, i.e. CMT's crossing swap
    frames (``com``'s ``crossing_swap_frames``, summed over the runs) are fewer than MTb+CPD's
    (``ewom``'s); equal counts, zero included, do not meet it."""
    before, after = ewom["crossing_swap_frames"], com["crossing_swap_frames"]
    return {
        "goal": f"{family}: SE on the crossings falls with COM (MTb+CPD -> CMT)",
        "value": f"{before} -> {after} swap frames of {com['crossing_frames']} "
        f"({scenes} scenes x {tracker_seeds} tracker seeds)",
        "met": after < before,
    }


def _empty_cases() -> dict[str, int]:
    return dict.fromkeys(("crossing_swap_frames", *OUTCOMES, "unscored"), 0)


def _empty_totals() -> dict[str, Any]:
    return {"IDSW": 0.0, "IDF1": 0.0, "MOTA": 0.0, "crossing_frames": 0, **_empty_cases()}


def table_markdown(record: dict[str, Any]) -> str:
    """``table.md``: the table, Fig. 9's gaps, the goals."""
    seeds = record["scene_seeds"]
    gap_rows = [
        {"family": family, **{k: f"{v:.2f}" for k, v in gap.items()}}
        for family, gap in record["fig9_gap"].items()
    ]
    lines = [
        "# CMT: COM against EWOM on the scripted crossings, by how alike the pair dress",
        "",
        f"Scene seeds {', '.join(map(str, seeds))} in each family (`crossing_alike`); tracker "
        f"seeds {', '.join(map(str, record['tracker_seeds']))}. Swap frames, crossing frames "
        "and the pair's identity outcomes (kept / switched / lost across the crossing) are "
        "summed over scenes and tracker seeds; IDSW, IDF1 and MOTA are the whole scenes', "
        "pooled, means over the tracker seeds. Configuration (both variants): "
        + (json.dumps(record["config"]) if record["config"] else "the defaults")
        + ".",
        "",
        markdown_table(record["rows"], COLUMNS),
        "",
        "## Fig. 9's likelihood gap between the pair (no tracker)",
        "",
        "`log p(z_A | m_A) - log p(z_B | m_A)` averaged over each scene's frames from before "
        "the crossing to its end, then over the scenes; `COM_above`: the share of frames where "
        "COM's gap exceeds EWOM's.",
        "",
        markdown_table(gap_rows, ("family", "COM", "EWOM", "COM_above")),
        "",
        "## Goals",
        "",
        *[f"- {line}" for line in goal_lines(record["goals"])],
    ]
    lines += [f"\n{line}" for line in environment_lines(record)]
    return "\n".join(lines) + "\n"
