"""The limits on every number that enters jaxtrack from a file or a command-line option.

Each quantity has one rule, checked once where it enters (the file reader, the option parser,
the configuration loader) and nowhere else. A violation is an
:class:`~jaxtrack.errors.InputError` (a :class:`~jaxtrack.errors.FileFormatError` naming the
file and line for data files; the key or the option otherwise), so that the CLI prints one
line and exits with status 2. A value that is legal but suspicious gives an
:class:`~jaxtrack.errors.InputWarning` (a Python warning; the CLI prints it as one line
``jaxtrack COMMAND: warning: ...`` on stderr) and the run goes on.

The limits are chosen to be general, not tuned to one data set:

* frames: at most :data:`MAX_FRAMES` (10^6, about 9 hours at 30 frames/s), because padded
  arrays are sized by the number of frames;
* images: integer sides in ``[MIN_IMAGE_SIZE, MAX_IMAGE_SIZE]`` = ``[16, 65536]`` pixels
  (smaller is no frame a detector runs on; the uniform intensities span box sizes ``1..W``);
  more than :data:`MAX_ASPECT_RATIO` = 10 times wider than high (or higher than wide) is legal
  but suspicious (the property test finds empty results for such shapes);
* frame rates: ``[MIN_FRAME_RATE, MAX_FRAME_RATE]`` = ``[1, 1000]`` frames per second: the
  tracker's birth velocity range is ``0.4 * H / frame_rate`` pixels per frame, so below one
  frame per second targets could cross most of the image between two frames, which
  frame-to-frame tracking cannot follow (a property test finds empty results there), and
  1000 is a high-speed camera;
* box coordinates: within :data:`MAX_COORDINATE` = 2^20 pixels (16 times the largest image;
  float32 still resolves 1/8 pixel there), and within :data:`IMAGE_FACTOR` image sizes of the
  image when its size is known; widths and heights of detections and ground truth at least
  :data:`MIN_BOX_SIZE` = 1 pixel (a smaller box is no object a detector or an annotator
  reports; it usually means normalised coordinates);
* every real value that is cast to float32 must stay what it is: finite, ``|v| <= 3.4e38``
  and, unless 0, ``|v| >= 1.2e-38`` (the smallest normal float32; XLA flushes smaller values
  to 0);
* identities fit int32.

:data:`RULES` lists every rule; :func:`rules_markdown` renders it for the README.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from jaxtrack.errors import InputError

#: Largest frame number and number of frames of a sequence, a video or a simulation.
MAX_FRAMES = 1_000_000
#: Most detections (or ground-truth / result rows) in one frame of a file. Crowded MOT
#: sequences have a few hundred per frame. A frame's detections are padded to a power of two
#: in the tracker (crowded frames run in chunks of their own, :func:`~jaxtrack.filters.base.
#: plan_chunks`), and one PHD frame at 4096 slots takes about 10 s on a CPU core and draws
#: 131,072 birth particles; a file with more rows in a frame is refused, naming the file and
#: the frame (:func:`jaxtrack.resources.check_rows_per_frame`).
MAX_DETECTIONS_PER_FRAME = 4096
#: Smallest image width or height, pixels.
MIN_IMAGE_SIZE = 16
#: Largest image width or height, pixels (2^16).
MAX_IMAGE_SIZE = 65_536
#: A wider (or higher) image than this ratio gives a warning.
MAX_ASPECT_RATIO = 10
#: Smallest frame rate, frames per second (birth velocities up to 0.4 image heights per frame).
MIN_FRAME_RATE = 1.0
#: Largest frame rate, frames per second.
MAX_FRAME_RATE = 1000.0
#: Largest ``|x|``, ``|y|``, ``w``, ``h`` of a box, pixels (2^20 = 16 * MAX_IMAGE_SIZE).
MAX_COORDINATE = float(2**20)
#: Smallest width and height of a detection or ground-truth box, pixels.
MIN_BOX_SIZE = 1.0
#: With a known image size ``W x H``: ``w <= IMAGE_FACTOR * W``, ``h <= IMAGE_FACTOR * H``,
#: ``x`` in ``[-IMAGE_FACTOR * W, (IMAGE_FACTOR + 1) * W]`` and ``y`` likewise with ``H``.
IMAGE_FACTOR = 10
#: Largest ``|score|`` of a detection or result row (scores are summed in float32).
MAX_SCORE = 1e6
#: Largest identity (int32).
MAX_ID = int(np.iinfo(np.int32).max)
#: Largest magnitude a float32 holds.
FLOAT32_MAX = float(np.finfo(np.float32).max)
#: Smallest non-zero magnitude a float32 holds without flushing to zero (smallest normal).
FLOAT32_TINY = float(np.finfo(np.float32).tiny)
#: Largest random seed (the seeds are 32-bit).
MAX_SEED = 2**32 - 1


@dataclasses.dataclass(frozen=True)
class Rule:
    """The rule of one value: a configuration key, a ``seqinfo.ini`` key or an option.

    Rules, one per kind of value:

    * ``int``: an integer (not a bool) within ``[lower, upper]``;
    * ``float``: a finite number (an int is accepted) within the bounds (each bound
      inclusive or exclusive), that a float32 holds without overflow or flush to zero
      (``|v| <= 3.4e38`` and ``v == 0`` or ``|v| >= 1.2e-38``);
    * ``str``: one of the choices;
    * ``tuple``: a list of exactly ``length`` floats, each following the float rule.

    Attributes:
        doc: what the value means, in words (shown by ``--help`` and in errors).
        kind: ``int``, ``float``, ``str`` or ``tuple``.
        lower: smallest allowed value (None: unbounded).
        upper: largest allowed value (None: unbounded).
        lower_open: the lower bound itself is excluded.
        upper_open: the upper bound itself is excluded.
        choices: the allowed strings (``str`` fields).
        length: the number of items (``tuple`` fields).
    """

    doc: str
    kind: type
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False
    upper_open: bool = False
    choices: tuple[str, ...] = ()
    length: int = 0

    def check(self, key: str, value: Any) -> Any:
        """``value`` converted to the rule's type.

        Raises:
            InputError: naming ``key``, when the value breaks the rule.
        """
        if self.kind is str:
            if value not in self.choices:
                raise InputError(f"{key} must be one of {', '.join(self.choices)}, got {value!r}")
            return value
        if self.kind is tuple:
            if not isinstance(value, list | tuple) or len(value) != self.length:
                raise InputError(f"{key} must be a list of {self.length} numbers, got {value!r}")
            return tuple(self._number(f"{key}[{i}]", item) for i, item in enumerate(value))
        return self._number(key, value)

    def _number(self, key: str, value: Any) -> int | float:
        integer = self.kind is int
        if isinstance(value, bool) or not isinstance(value, int if integer else int | float):
            kind = "an integer" if integer else "a number"
            raise InputError(f"{key} must be {kind}, got {_short(value)}")
        given = value
        if not integer:
            try:
                value = float(value)
            except OverflowError:
                value = math.inf if value > 0 else -math.inf
            if not math.isfinite(value):
                raise InputError(f"{key} must be finite, got {_short(given)}")
        low_bad = self.lower is not None and (
            value <= self.lower if self.lower_open else value < self.lower
        )
        high_bad = self.upper is not None and (
            value >= self.upper if self.upper_open else value > self.upper
        )
        if low_bad or high_bad:
            raise InputError(f"{key} must lie in {self.interval()}, got {_short(given)}")
        if not integer and float32_trouble(value):
            raise InputError(
                f"{key} = {value!r} is not representable in float32 "
                f"(|v| <= {FLOAT32_MAX:.4g} and 0 or |v| >= {FLOAT32_TINY:.4g})"
            )
        return value

    def interval(self) -> str:
        """The allowed range in interval notation, e.g. ``(0, 1]``."""
        low = "-inf" if self.lower is None else _bound(self.lower)
        high = "inf" if self.upper is None else _bound(self.upper)
        left = "(" if self.lower_open or self.lower is None else "["
        right = ")" if self.upper_open or self.upper is None else "]"
        return f"{left}{low}, {high}{right}"


def _bound(value: float) -> str:
    """A bound as written in an interval: integers in full (below 2^53), others with ``%g``."""
    if float(value).is_integer() and abs(value) < 2**53:
        return str(int(value))
    return f"{value:g}"


def _short(value: Any) -> str:
    """``repr(value)``, cut to 40 characters (a 400-digit integer stays readable)."""
    text = repr(value)
    return text if len(text) <= 40 else f"{text[:30]}...({len(text)} characters)"


#: ``seqLength``, a video's frame count, ``--num-frames``, a scene's ``num_frames``.
FRAME_COUNT = Rule("number of frames", int, 1, MAX_FRAMES)
#: A 1-based frame number (files, ``--figure-frame``, ``--preview-frame``).
FRAME_NUMBER = Rule("1-based frame number", int, 1, MAX_FRAMES)
#: ``imWidth``, ``imHeight``, a video's frame size, a scene's ``image_width/height``.
IMAGE_SIZE = Rule("image width or height, pixels", int, MIN_IMAGE_SIZE, MAX_IMAGE_SIZE)
#: ``frameRate``, ``--fps``, a video's own rate, a scene's ``frame_rate``.
FRAME_RATE = Rule("frames per second", float, MIN_FRAME_RATE, MAX_FRAME_RATE)
#: ``--seed``.
SEED = Rule("random seed", int, 0, MAX_SEED)


def float32_trouble(values) -> np.ndarray:
    """True where a value does not survive a cast to float32 unchanged in kind.

    That is: not finite, ``|v| > FLOAT32_MAX`` (becomes inf), or ``0 < |v| < FLOAT32_TINY``
    (becomes 0, or a denormal that XLA flushes to 0).
    """
    values = np.asarray(values, dtype=np.float64)
    magnitude = np.abs(values)
    with np.errstate(invalid="ignore"):
        return (
            ~np.isfinite(values)
            | (magnitude > FLOAT32_MAX)
            | ((magnitude > 0) & (magnitude < FLOAT32_TINY))
        )


@dataclasses.dataclass(frozen=True)
class Limit:
    """One documented rule.

    Attributes:
        quantity: what is checked.
        where: the files, keys and options it comes from.
        rule: the rule, in words.
        outcome: ``error`` (exit 2) or ``warning`` (stderr, the run goes on).
    """

    quantity: str
    where: str
    rule: str
    outcome: str = "error"


_F32 = "finite, |v| <= 3.4e38, and 0 or |v| >= 1.2e-38 (float32 without overflow or flush)"

#: Every rule on numbers from files and options, in the order of the README table.
RULES: tuple[Limit, ...] = (
    Limit(
        "frame number",
        "MOT files (column 1); --frames A:B; --figure-frame; --preview-frame",
        f"integer in [1, {MAX_FRAMES:,}], and in [1, seqLength] when seqinfo.ini (or the "
        "video) is known; eval --gt/--res without --seqinfo sizes its arrays by the largest "
        "frame, so the absolute bound applies",
    ),
    Limit(
        "number of frames",
        "seqinfo.ini seqLength; video frame count; simulate --num-frames, num_frames; "
        "label-clutter --num-frames",
        f"integer in [1, {MAX_FRAMES:,}]",
    ),
    Limit(
        "image width, height",
        "seqinfo.ini imWidth, imHeight; video frame size; scene image_width, image_height",
        f"integer in [{MIN_IMAGE_SIZE}, {MAX_IMAGE_SIZE}] pixels",
    ),
    Limit(
        "image aspect ratio",
        "seqinfo.ini imWidth, imHeight",
        f"more than {MAX_ASPECT_RATIO} times wider than high, or higher than wide",
        "warning",
    ),
    Limit(
        "frame rate",
        "seqinfo.ini frameRate (optional); --fps; scene frame_rate",
        f"number in [{MIN_FRAME_RATE:g}, {MAX_FRAME_RATE:g}] frames/s",
    ),
    Limit(
        "frame rate of a video file",
        "the video header",
        f"outside [{MIN_FRAME_RATE:g}, {MAX_FRAME_RATE:g}]: ignored as unknown (give --fps)",
        "warning",
    ),
    Limit(
        "box x, y",
        "MOT files (columns 3-4)",
        f"{_F32}; |x|, |y| <= 2^20 px; with a known W x H image: x in [-{IMAGE_FACTOR}W, "
        f"{IMAGE_FACTOR + 1}W], y in [-{IMAGE_FACTOR}H, {IMAGE_FACTOR + 1}H]",
    ),
    Limit(
        "box w, h",
        "MOT files (columns 5-6)",
        f"det and gt: in [{MIN_BOX_SIZE:g}, 2^20] px; results: in (0, 2^20] px (float32 "
        f"normal); with a known image: w <= {IMAGE_FACTOR}W, h <= {IMAGE_FACTOR}H",
    ),
    Limit(
        "boxes outside the image",
        "MOT files with a known image size",
        "every box of a file lies outside the W x H image: the image size or the coordinates "
        "are probably wrong",
        "warning",
    ),
    Limit(
        "score (conf)",
        "MOT files (column 7)",
        f"{_F32}; |conf| <= {MAX_SCORE:g}",
    ),
    Limit(
        "detection score outside [0, 1]",
        "det files (column 7)",
        "the PHD tracker's score rules (confirm_score) and the Kalman tracker's min_score "
        "assume probabilities",
        "warning",
    ),
    Limit(
        "detections below a tracker's min_score",
        "det files (column 7), with the Kalman tracker's default preset or a min_score setting",
        "half or more of a sequence's detections score below the threshold (the Kalman "
        "default preset's 0.9 was chosen on MOT15's detector) and are ignored",
        "warning",
    ),
    Limit("extra columns", "MOT files (columns 8-10)", _F32),
    Limit(
        "identity",
        "MOT files (column 2)",
        f"integer; det: in [-1, {MAX_ID}]; gt and results: in [0, {MAX_ID}] (-1 marks the "
        "padded slots), unique within a frame",
    ),
    Limit(
        "no detections",
        "det.txt of a sequence folder",
        "the file, or the --frames span, holds no detection: tracking gives no tracks",
        "warning",
    ),
    Limit(
        "seqLength far beyond the data",
        "seqinfo.ini with det.txt",
        "no detection or gt row in the second half of 1..seqLength: tracking runs over empty "
        "frames",
        "warning",
    ),
    Limit(
        "learned context (.npz)",
        "--context; context_truth.npz",
        "arrays of real numbers, finite, |v| <= 3.4e38; magnitude in [0, 1e4] events/frame "
        "(0 or >= 1.2e-38), also the magnitudes recorded in its metadata; uniform_weight in "
        "[0, 1]; lower, upper, means within +-2^20, upper > lower in float32; weights >= 0 "
        "summing to 1; every covariance symmetric and positive definite (Cholesky in float64 "
        "and, as the filters factor it, in float32); the error names the field",
    ),
    Limit(
        "tracker configuration",
        "--config FILE.json (every key)",
        "each key's type and range (jaxtrack track --help); floats also " + _F32 + "; NaN, "
        "Infinity and unknown keys are errors",
    ),
    Limit(
        "scene configuration",
        "simulate --scene-config FILE.json",
        "each field's range (jaxtrack.datasets.scene_config.SceneConfig); NaN and "
        "Infinity are errors",
    ),
    Limit(
        "random seed",
        "--seed",
        f"integer in [0, {MAX_SEED}]",
    ),
    Limit(
        "other numeric options",
        "every command",
        "each option's range (jaxtrack.commands.arguments: IoU in (0, 1], distances and "
        "OSPA cut-off in (0, 2^20], OSPA order in [1, 10], epochs in [1, 10^4], steps in "
        "[1, 10^6], keys in [1, 1024], learning rate in (0, 100], particles as the tracker "
        "configuration's); the error names the option",
    ),
)


def rules_markdown() -> str:
    """:data:`RULES` as a Markdown table (for the README)."""
    lines = ["| Quantity | From | Rule | Outcome |", "|---|---|---|---|"]
    for limit in RULES:
        cells = (limit.quantity, limit.where, limit.rule, limit.outcome)
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
    return "\n".join(lines)
