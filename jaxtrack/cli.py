"""The ``jaxtrack`` command: one sub-command per module in :mod:`jaxtrack.commands`.

Each command module defines ``register(subparsers)`` which adds its parser and sets
``func(args) -> int`` as the parser default. Bad input (any :class:`jaxtrack.InputError`,
a bad command line included: an unknown option, an invalid choice, a number out of its range)
is printed as ``jaxtrack <command>: error: <message>`` without a traceback, exit status 2; an
:class:`jaxtrack.errors.InputWarning` (a legal but suspicious value) as one line
``jaxtrack <command>: warning: <message>`` on stderr, and the command goes on.
"""

from __future__ import annotations

import argparse
import importlib
import sys
import warnings

from jaxtrack import __version__
from jaxtrack.commands.arguments import CommandParser, UsageError
from jaxtrack.errors import InputError, InputWarning
from jaxtrack.pipelines.runtime import (
    use_compilation_cache,
    use_cpu_cores,
    use_cpu_threads,
    use_cpu_vector_width,
)

#: Command modules under jaxtrack.commands, in the order ``--help`` lists them.
COMMANDS = (
    "demo",
    "simulate",
    "inspect",
    "track",
    "eval",
    "label_clutter",
    "learn_context",
    "learn_zones",
    "tune",
    "detect",
    "track_video",
    "experiment",
)


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(
        prog="jaxtrack",
        description=(
            "Context-aware multi-object tracking in JAX: particle PHD filter with learned "
            "scene context, MOTChallenge data tools and TrackEval-exact metrics."
        ),
    )

    parser.add_argument("--version", action="version", version=f"jaxtrack {__version__}")
    subparsers = parser.add_subparsers(
        dest="command", metavar="COMMAND", required=True, parser_class=CommandParser
    )
    for name in COMMANDS:
        importlib.import_module(f"jaxtrack.commands.{name}").register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except UsageError as err:
        print(f"{err.prog}: error: {err}", file=sys.stderr)
        return 2
    use_cpu_cores()  # a sweep's configurations run on every core (no effect on one run)
    if runs_the_phd_tracker(args):
        use_cpu_threads()  # XLA's pool at one thread: faster small kernels, the same results
        use_cpu_vector_width()  # 512-bit vectors (AVX-512), plain min/max: the same results
    use_compilation_cache()  # a later run of the same setting skips the compile
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warnings(args.command, warnings.showwarning)
            return int(args.func(args) or 0)
    except InputError as err:
        print(f"jaxtrack {args.command}: error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"jaxtrack {args.command}: interrupted", file=sys.stderr)
        return 130


#: The commands whose work is the PHD tracker when ``--tracker`` is phd (or absent).
PHD_COMMANDS = ("track", "track_video", "tune")


def runs_the_phd_tracker(args: argparse.Namespace) -> bool:
    """True when the command's work is the PHD tracker's ``lax.scan``: ``track``,
    ``track-video`` and ``tune`` with ``--tracker phd`` (the default).

    There the command sizes XLA's CPU thread pool at one thread
    (:func:`~jaxtrack.pipelines.runtime.use_cpu_threads`): a PHD frame is about 200 small
    kernels, which the pool's split and wait slow down. It also asks for 512-bit vectors
    and plain min/max where the CPU has AVX-512
    (:func:`~jaxtrack.pipelines.runtime.use_cpu_vector_width`). The other trackers' frames
    hold image-sized work that the pool speeds up (Fusion and Hierarchical ran 15-30 %
    slower on one thread), so they keep XLA's defaults (their code generation was not
    measured).
    """
    command = args.command.replace("-", "_")
    return command in PHD_COMMANDS and getattr(args, "tracker", "phd") == "phd"


def _one_line_warnings(command: str, show):
    """``warnings.showwarning`` that prints an InputWarning as ``jaxtrack CMD: warning: ...``
    (one line on stderr) and leaves other warnings to ``show``."""

    def showwarning(message, category, filename, lineno, file=None, line=None):
        if issubclass(category, InputWarning):
            print(f"jaxtrack {command}: warning: {message}", file=sys.stderr)
        else:
            show(message, category, filename, lineno, file, line)

    return showwarning


if __name__ == "__main__":
    sys.exit(main())
