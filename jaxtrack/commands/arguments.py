"""The arguments every ``jaxtrack`` command shares, so that a flag means the same everywhere.

``--frames A:B`` is always a 1-based inclusive span, ``--seed N`` defaults to 0, ``--config
FILE.json`` is always a tracker configuration, ``--quiet`` turns progress bars off and
``--json`` prints the results as one JSON object. Commands import each other's helpers only
through this module (``load_config``, ``add_context_arguments``).

Every numeric option is range-checked where it is parsed: ``type=ranged(RULE)`` with one of
the rules below (or :mod:`jaxtrack.limits`'s ``FRAME_NUMBER``, ``FRAME_COUNT``,
``FRAME_RATE``, ``SEED``); argparse names the option in the error and exits with status 2.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable

from jaxtrack.configs import MAX_RETRODICTION, TrackerConfig, load_config_file
from jaxtrack.errors import InputError
from jaxtrack.filters.fusion import FUSIONS, MEMBERS
from jaxtrack.filters.fusion_tracker import FusionConfig
from jaxtrack.filters.phd_tracker import (
    MAX_BIRTHS_PER_DETECTION,
    MAX_PARTICLES,
    VARIANTS,
)
from jaxtrack.filters.registry import TRACKERS, tracker_entry
from jaxtrack.io import parse_frame_span
from jaxtrack.limits import MAX_COORDINATE, MAX_FRAMES, MAX_SEED, SEED, Rule

#: An IoU threshold (``--iou``, ``--iou-threshold``).
IOU = Rule("IoU threshold", float, 0.0, 1.0, lower_open=True)
#: A distance in pixels (``--centre-threshold``) or an OSPA cut-off (``--ospa-c``).
DISTANCE = Rule("distance", float, 0.0, MAX_COORDINATE, lower_open=True)
#: The OSPA/GOSPA order ``p`` (``--ospa-p``; ``d^p`` must stay finite).
OSPA_ORDER = Rule("OSPA order", float, 1.0, 10.0)
#: A number of frames that may be 0 (``--warmup``, ``--trail``).
FRAMES_OR_NONE = Rule("frames", int, 0, MAX_FRAMES)
#: Frames for a background model (``--train-frames``; at least 3).
TRAIN_FRAMES = Rule("training frames", int, 3, MAX_FRAMES)
#: Passes over learning events (``--birth-epochs``, ``--clutter-epochs``).
EPOCHS = Rule("epochs", int, 1, 10_000)
#: Optimiser steps (``--steps``) and patience (``--patience``, 0: never stop early).
STEPS = Rule("steps", int, 1, 1_000_000)
PATIENCE = Rule("steps", int, 0, 1_000_000)
#: PRNG keys per tuning step (``--keys``).
KEYS = Rule("keys", int, 1, 1024)
#: Adam learning rate (``--learning-rate``).
LEARNING_RATE = Rule("learning rate", float, 0.0, 100.0, lower_open=True)
#: Particles (``--particles``) and birth particles per detection, as the tracker config's.
PARTICLES = Rule("particles", int, 1, MAX_PARTICLES)
#: ``PHDConfig.retrodiction``.
RETRODICTION = Rule("frames", int, 0, MAX_RETRODICTION)
BIRTHS_PER_DETECTION = Rule("birth particles per detection", int, 1, MAX_BIRTHS_PER_DETECTION)


class UsageError(InputError):
    """A bad command line (argparse's error), raised instead of printing the usage and exiting.

    Attributes:
        prog: the (sub-)command whose arguments are wrong, e.g. ``jaxtrack track``.
    """

    def __init__(self, prog: str, message: str):
        self.prog = prog
        super().__init__(f"{message} (see {prog} --help)")


class CommandParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise :class:`UsageError`, so that the CLI prints a bad
    argument as one line and exits 2 like every other bad input (``--help`` still exits 0)."""

    def error(self, message: str):
        raise UsageError(self.prog, message)


def ranged(rule: Rule) -> Callable[[str], int | float]:
    """An argparse ``type=``: the option's text as an int or float that keeps ``rule``.

    Raises (inside argparse):
        argparse.ArgumentTypeError: not a number of the rule's kind, or out of its range;
            argparse prints ``argument --OPTION: value must lie in [a, b], got x`` and exits 2.
    """
    kind = "an integer" if rule.kind is int else "a number"

    def parse(text: str) -> int | float:
        try:
            value = int(text) if rule.kind is int else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be {kind} in {rule.interval()}, got {text[:40]!r}"
            ) from None
        try:
            return rule.check("value", value)
        except InputError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    parse.__name__ = rule.doc
    return parse


#: Help of ``--frames`` (every command).
FRAMES_HELP = "frame span A:B (1-based, inclusive; A: or :B leave an end open)"
#: Help of ``--seed`` (every command).
SEED_HELP = f"random seed in [0, {SEED.upper}] (default 0)"
#: Help of ``--config`` (every command).
CONFIG_HELP = (
    "tracker configuration: a JSON object whose keys override the tracker's defaults "
    "(see jaxtrack track --help; jaxtrack tune writes one)"
)
#: Help of ``--quiet`` (every command).
QUIET_HELP = "no progress bars or step messages"
#: Help of ``--json`` (every command).
JSON_HELP = "print the results as one JSON object instead of a table"


#: The ``type=`` of ``--seed`` (every command): an integer in ``[0, 2^32 - 1]``.
SEED_TYPE = ranged(SEED)
#: A number of consecutive seeds (``--num-seeds``, ``--real-seeds``, ``--tracker-seeds``).
SEED_COUNT_TYPE = ranged(Rule("number of seeds", int, 1, 1000))


def consecutive_seeds(first: int, count: int, option: str) -> list[int]:
    """Seeds ``first .. first + count - 1``.

    Raises:
        InputError: the last one above :data:`~jaxtrack.limits.MAX_SEED` (``--seed +
            OPTION - 1`` named).
    """
    seeds = list(range(first, first + count))
    if seeds[-1] > MAX_SEED:
        raise InputError(f"--seed + {option} - 1 must be at most {MAX_SEED}")
    return seeds


def add_frames(parser: argparse.ArgumentParser) -> None:
    """Adds ``--frames A:B`` (read with :func:`jaxtrack.io.parse_frame_span`)."""
    parser.add_argument("--frames", metavar="A:B", help=FRAMES_HELP)


def add_seed(parser: argparse.ArgumentParser) -> None:
    """Adds ``--seed N`` (default 0)."""
    parser.add_argument("--seed", type=SEED_TYPE, default=0, metavar="N", help=SEED_HELP)


def add_out(
    parser: argparse.ArgumentParser,
    help: str,
    required: bool = True,
    metavar: str = "PATH",
    default: str | None = None,
) -> None:
    """Adds ``--out PATH``: what the command writes (``help`` says what)."""
    parser.add_argument("--out", required=required, default=default, metavar=metavar, help=help)


def add_config(parser: argparse.ArgumentParser) -> None:
    """Adds ``--config FILE.json``: always a tracker configuration (:func:`load_config`)."""
    parser.add_argument("--config", metavar="FILE.json", help=CONFIG_HELP)


def add_quiet(parser: argparse.ArgumentParser) -> None:
    """Adds ``--quiet``: progress bars off (``progress=not args.quiet``)."""
    parser.add_argument("--quiet", action="store_true", help=QUIET_HELP)


def add_json(parser: argparse.ArgumentParser) -> None:
    """Adds ``--json``: one JSON object on stdout instead of the table."""
    parser.add_argument("--json", action="store_true", help=JSON_HELP)


def add_tracker(parser: argparse.ArgumentParser) -> None:
    """Adds ``--tracker NAME``, one of the registry's trackers (default phd)."""
    parser.add_argument(
        "--tracker", choices=list(TRACKERS), default="phd", help="which tracker (default phd)"
    )


def add_context_arguments(
    parser: argparse.ArgumentParser,
    variants_doc: str,
    tracker_variants: tuple[str, ...] = (),
    with_um: bool = False,
) -> None:
    """Adds ``--context CTX.npz`` and ``--variant`` (``jaxtrack track``, ``track-video``);
    ``tracker_variants`` are further ``--variant`` choices that pick a tracker's variant
    (CMT's ablation) rather than a context's parts; ``with_um`` also offers UM (uniform
    intensities that read only the context's detector score calibration)."""
    parser.add_argument(
        "--context", metavar="CTX.npz", help="learned context (jaxtrack learn-context)"
    )
    parser.add_argument(
        "--variant",
        choices=[name for name in VARIANTS if with_um or name != "UM"] + list(tracker_variants),
        help=f"which parts of --context to use (default GM; {variants_doc})",
    )


def add_variant_and_scene_arguments(parser: argparse.ArgumentParser, see: str) -> None:
    """``--context`` and ``--variant`` (a context's parts, or a tracker's own variants) and
    ``--zones`` (CMT's entry/exit zones): the options of ``jaxtrack track`` and
    ``track-video`` that pick what a tracker knows of the scene; ``see`` says where the
    context's variants are explained."""
    add_context_arguments(
        parser,
        f"{see}; mtb, cpd, cmt for --tracker cmt; kalman, managed, full for --tracker hierarchical",
        tuple(tracker_variant_names()),
        with_um=True,
    )
    parser.add_argument(
        "--zones",
        metavar="ZONES.json",
        help="entry/exit zones for --tracker cmt (jaxtrack learn-zones; default: learned on "
        "the fly from the tracked span)",
    )


def parse_pool(text: str) -> str:
    """An argparse ``type=`` for ``--pool``: comma-separated members in any order, each once,
    as :class:`~jaxtrack.filters.fusion_tracker.FusionConfig`'s ``pool`` (MEMBERS order).

    Raises (inside argparse):
        argparse.ArgumentTypeError: no member, an unknown one (the members are listed) or
            one named twice.
    """
    names = [name.strip() for name in text.split(",")]
    members = ", ".join(MEMBERS)
    if not any(names):
        raise argparse.ArgumentTypeError(f"name at least one member of {members}")
    unknown = [name for name in names if name not in MEMBERS]
    if unknown:
        raise argparse.ArgumentTypeError(
            f"unknown member {unknown[0][:40]!r}; the members are {members}"
        )
    if len(set(names)) < len(names):
        raise argparse.ArgumentTypeError(f"a member named twice in {text[:80]!r}")
    return ",".join(name for name in MEMBERS if name in names)


def add_fusion_arguments(parser: argparse.ArgumentParser, train_note: str = "") -> None:
    """``--pool``, ``--fusion`` and ``--train-frames``: the options of ``jaxtrack track`` and
    ``track-video`` that set up the Fusion tracker (:func:`apply_fusion_arguments`);
    ``train_note`` ends ``--train-frames``'s help."""
    parser.add_argument(
        "--pool",
        type=parse_pool,
        metavar="MEMBERS",
        help=f"--tracker fusion's pool: comma-separated members, any non-empty subset of "
        f"{','.join(MEMBERS)} in any order (default all three; one member: that tracker alone)",
    )
    parser.add_argument(
        "--fusion",
        choices=FUSIONS,
        help="--tracker fusion's rule: proposed (confidence and accordance, default) or naive "
        "(the mean of the members' responses)",
    )
    parser.add_argument(
        "--train-frames",
        metavar="A:B",
        help="--tracker fusion's training span, where it learns its zones, motion models and "
        "voting thresholds (1-based, inclusive, inside the tracked frames; default: the first "
        f"half of the tracked frames){train_note}",
    )


def apply_fusion_arguments(args: argparse.Namespace, config: TrackerConfig) -> TrackerConfig:
    """The configuration with ``--pool`` and ``--fusion``; refuses them and
    ``--train-frames`` for a tracker other than the Fusion tracker.

    Raises:
        InputError: one of them given to another tracker (it would be ignored).
    """
    if not tracker_entry(args.tracker).takes_training:
        refuse_ignored(
            args, ["train_frames"], f"applies to --tracker fusion, not to {args.tracker}"
        )
    if not isinstance(config, FusionConfig):
        refuse_ignored(
            args, ["pool", "fusion"], f"applies to --tracker fusion, not to {args.tracker}"
        )
        return config
    changes = {name: getattr(args, name) for name in ("pool", "fusion")}
    return config.replace(**{name: value for name, value in changes.items() if value is not None})


def check_train_frames(text: str | None, tracked: tuple[int, int], seq_length: int) -> None:
    """Refuses a ``--train-frames`` span that is malformed or outside the tracked frames,
    before any work (the span is read as ``--frames`` is, against the whole sequence).

    Raises:
        InputError: ``--train-frames`` named, with the reason.
    """
    if text is None:
        return
    try:
        start, end = parse_frame_span(text, seq_length)
    except InputError as err:
        raise InputError(f"--train-frames {text[:40]}: {err}") from None
    if not tracked[0] <= start <= end <= tracked[1]:
        raise InputError(
            f"--train-frames {start}:{end} must lie inside the tracked frames "
            f"{tracked[0]}:{tracked[1]}"
        )


#: The ``--variant`` used with ``--context`` when none is given.
DEFAULT_VARIANT = "GM"


def tracker_variant_names() -> list[str]:
    """Every tracker's own variants (``--variant`` choices beside the context's parts)."""
    return [name for entry in TRACKERS.values() for name in entry.variants]


def apply_tracker_variant(args: argparse.Namespace, config: TrackerConfig) -> TrackerConfig:
    """The configuration with ``--variant`` when it names one of the tracker's own variants.

    Raises:
        InputError: another tracker's variant, or a context variant for a tracker with
            variants of its own.
    """
    own = tracker_entry(args.tracker).variants
    if args.variant in own:
        return config.replace(variant=args.variant)
    for name, entry in TRACKERS.items():
        if args.variant in entry.variants:
            raise InputError(f"--variant {args.variant} applies to --tracker {name}")
    if own and args.variant is not None:
        raise InputError(
            f"--variant {args.variant} is a PHD context variant; {args.tracker}'s are "
            f"{', '.join(own)}"
        )
    return config


def context_variant(args: argparse.Namespace) -> str | None:
    """The variant of ``--context``: ``--variant``, else GM; None without ``--context``.

    Raises:
        InputError: ``--variant`` without ``--context`` (it would be ignored: UM is run).
    """
    if args.context is None:
        refuse_ignored(args, ["variant"], "needs --context (without one the tracker runs UM)")
        return None
    return args.variant or DEFAULT_VARIANT


def refuse_ignored(args: argparse.Namespace, names: Iterable[str], reason: str) -> None:
    """Refuses the first of the options ``names`` that was given, as it would be ignored.

    Args:
        args: the parsed arguments; an option counts as given unless it is None or False.
        names: the options' attribute names (``figure_frame`` for ``--figure-frame``).
        reason: why it would be ignored, after the flag (``needs --figure``).

    Raises:
        InputError: ``--<name> <reason>``.
    """
    for name in names:
        value = getattr(args, name)
        if value is not None and value is not False:
            raise InputError(f"--{name.replace('_', '-')} {reason}")


def load_config(path: str | None, tracker: str = "phd") -> TrackerConfig:
    """The configuration of ``tracker``: its defaults, or the ``--config`` file at ``path``.

    Raises:
        InputError: an unknown tracker; FileFormatError: a missing or bad file, an unknown
            key or a bad value (named).
    """
    config_type = tracker_entry(tracker).config_type
    return config_type() if path is None else load_config_file(path, config_type)


def step_progress(bar) -> Callable[[str], None]:
    """A pipeline's ``progress`` callback on a tqdm bar counting steps: each message names
    the step now starting (the bar's description) and completes the one before it."""
    started = False

    def progress(message: str) -> None:
        nonlocal started
        if started:
            bar.update(1)
        started = True
        bar.set_description_str(message)

    return progress
