"""What a command writes, checked against what it reads, before any work is done.

Every command lists the files and folders it will write (:class:`Output`, side files such as
``<RES>.config.json`` included) and those it reads (:class:`Input`), and calls
:func:`check_outputs` before it loads, computes or writes anything. A run is refused (an
:class:`~jaxtrack.errors.InputError` naming the option) when an output

* is one of its inputs (paths resolved: symlinks, ``..``, and the same file under two names
  via :func:`os.path.samefile`), or would add an image to an image folder the run reads;
* is an existing folder where a file is written, or an existing file where a folder is;
* cannot be written: a file on the way to it, or an existing file or the nearest existing
  folder not writable (:func:`os.access`);
* is the path of another output of the same run (or lies inside an output file).

Writing a new file into a sequence folder (``SEQ/results.txt``) is fine; writing over its
``seqinfo.ini``, ``det/det.txt``, ``gt/gt.txt``, ``context_truth.npz``, a frame of ``img1/``
or its video is not, whether or not this run reads that file: the next run would.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import NamedTuple

from matplotlib.backend_bases import FigureCanvasBase

from jaxtrack.errors import InputError
from jaxtrack.io.video import IMAGE_EXTENSIONS, VIDEO_EXTENSIONS

#: Names of the PNG frames :class:`jaxtrack.io.video.FrameWriter` writes into a folder.
FRAME_PNG = re.compile(r"\d{6}\.png")
#: The files of a sequence folder, and what they are.
SEQUENCE_FILES = (
    (("seqinfo.ini",), "the sequence information"),
    (("det", "det.txt"), "the detections"),
    (("gt", "gt.txt"), "the ground truth"),
    (("context_truth.npz",), "the true context"),
)
#: The files ``jaxtrack simulate`` (and an experiment's synthetic scene) writes into a folder.
SCENE_FILES = ("seqinfo.ini", "det/det.txt", "gt/gt.txt", "context_truth.npz", "preview.png")


class Output(NamedTuple):
    """A file or folder a command writes.

    Attributes:
        option: the option that names it (``--out``).
        given: the path as the option gave it.
        path: the path written: ``given``, or a file derived from it (a side file, a file
            inside an output folder).
        folder: a folder (created if needed) rather than a file.
        names: for a folder, the pattern of the names of the files written directly into it
            that are not listed as outputs of their own (PNG frames), or None.
    """

    option: str
    given: str
    path: Path
    folder: bool = False
    names: re.Pattern | None = None

    @property
    def label(self) -> str:
        """How messages name it: ``--out r.txt``, or ``r.config.json (written with --out ...)``."""
        named = f"{self.option} {self.given}"
        return named if self.path == Path(self.given) else f"{self.path} (written with {named})"


class Input(NamedTuple):
    """A file a command reads, or a folder it reads as a whole.

    Attributes:
        path: the file or folder (need not exist: writing a sequence's ``gt/gt.txt`` is refused
            even where the sequence has none yet).
        what: what it is, in words (``the detections of SEQ``).
        image_folder: a folder of images read as a whole: every image written into it
            would become a frame.
    """

    path: Path
    what: str
    image_folder: bool = False


def output_file(option: str, given: str | os.PathLike, path: str | os.PathLike | None = None):
    """The file ``option`` names (``path``: a file derived from it, written with it)."""
    return Output(option, str(given), Path(given if path is None else path))


def side_file(option: str, given: str | os.PathLike, suffix: str) -> Output:
    """The file written beside ``given`` with its suffix replaced (``RES.config.json``)."""
    base = Path(given)
    stem = base.with_suffix("") if base.name not in ("", "..") else base
    return output_file(option, given, f"{stem}{suffix}")


def output_folder(option: str, given: str | os.PathLike, files: Iterable[str] = ()) -> list:
    """The folder ``option`` names and the files written into it (relative paths)."""
    folder = Path(given)
    outputs = [Output(option, str(given), folder, folder=True)]
    return outputs + [output_file(option, given, folder / name) for name in files]


def frames_output(option: str, given: str | os.PathLike) -> Output:
    """Frames written by :class:`~jaxtrack.io.video.FrameWriter`: a video file, else PNGs."""
    if Path(given).suffix.lower() in VIDEO_EXTENSIONS:
        return output_file(option, given)
    return Output(option, str(given), Path(given), folder=True, names=FRAME_PNG)


def figure_output(option: str, given: str | os.PathLike) -> Output:
    """A matplotlib figure file: its format must be one matplotlib writes (no suffix: PNG).

    Raises:
        InputError: an unknown format (matplotlib would fail after the work is done).
    """
    suffix = Path(given).suffix.lower()
    if not suffix:
        return output_file(option, given, f"{given}.png")  # matplotlib appends .png
    formats = FigureCanvasBase.get_supported_filetypes()
    if suffix[1:] not in formats:
        raise InputError(
            f"{option} {given}: matplotlib writes no {suffix} figures; use one of "
            + ", ".join(f".{name}" for name in sorted(formats))
        )
    return output_file(option, given)


def file_input(path: str | os.PathLike | None, what: str) -> list[Input]:
    """A file the run reads (none when ``path`` is None: the option was not given)."""
    return [] if path is None else [Input(Path(path), what)]


def video_input(path: str | os.PathLike | None, what: str) -> list[Input]:
    """A video file, or an image folder read as a whole (every image in it a frame)."""
    if path is None:
        return []
    if Path(path).is_dir():
        return [Input(Path(path), what, image_folder=True)]
    return [Input(Path(path), what)]


def sequence_inputs(folder: str | os.PathLike) -> list[Input]:
    """A MOTChallenge sequence folder's files: those of :data:`SEQUENCE_FILES`, the frames of
    ``img1/`` and the videos in the folder (whether or not this run reads them)."""
    root = Path(folder)
    inputs = [Input(root.joinpath(*parts), f"{what} of {folder}") for parts, what in SEQUENCE_FILES]
    inputs.append(Input(root / "img1", f"the frames of {folder}", image_folder=True))
    if root.is_dir():
        videos = (p for p in sorted(root.iterdir()) if p.suffix.lower() in VIDEO_EXTENSIONS)
        inputs += [Input(path, f"the video of {folder}") for path in videos if path.is_file()]
    return inputs


def benchmark_inputs(root: str | os.PathLike, folders: Iterable[Path]) -> list[Input]:
    """A benchmark root (not itself an output folder) and each sequence's files."""
    inputs = [Input(Path(root), f"the sequences of {root}")]
    for folder in folders:
        inputs += sequence_inputs(folder)
    return inputs


def same_path(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether two paths name the same file (resolved, or the same existing file)."""
    return _resolved(a) == _resolved(b) or _same_existing(a, b)


def check_outputs(outputs: Sequence[Output], inputs: Sequence[Input]) -> None:
    """Refuses outputs that overwrite an input, cannot be written, or collide (module doc).

    Raises:
        InputError: naming the option (and the input) of the first problem found.
    """
    for output in outputs:
        _check_kind(output)
        _check_writable(output)
        for source in inputs:
            _check_not_input(output, source)
    for i, first in enumerate(outputs):
        for second in outputs[i + 1 :]:
            _check_apart(first, second)


def _resolved(path: str | os.PathLike) -> Path:
    return Path(os.path.realpath(os.fspath(path)))


def _same_existing(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist
        return False


def _inside(path: Path, folder: Path) -> tuple[str, ...] | None:
    """The parts of resolved ``path`` below resolved ``folder``, or None when outside."""
    try:
        parts = path.relative_to(folder).parts
    except ValueError:
        return None
    return parts or None


def _check_kind(output: Output) -> None:
    path = output.path
    if output.folder and path.exists() and not path.is_dir():
        raise InputError(f"{output.label} exists and is not a folder (this option writes a folder)")
    if not output.folder and path.is_dir():
        raise InputError(
            f"{output.label} is a folder; give a file path (this option writes a file)"
        )


def _check_writable(output: Output) -> None:
    path = _resolved(output.path)
    if path.exists() and not os.access(path, os.W_OK):
        raise InputError(f"{output.label} is not writable")
    folder = path if output.folder else path.parent
    existing = folder
    while not os.path.lexists(existing):
        existing = existing.parent
    if not existing.is_dir():
        raise InputError(f"{output.label} cannot be written: {existing} is not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(f"{output.label} cannot be written: {existing} is not writable")


def _check_not_input(output: Output, source: Input) -> None:
    path, source_path = _resolved(output.path), _resolved(source.path)
    if path == source_path or _same_existing(output.path, source.path):
        raise InputError(f"{output.label} is an input of this run ({source.what})")
    if source.image_folder and path.parent == source_path:
        if path.suffix.lower() in IMAGE_EXTENSIONS:
            if path.exists():
                raise InputError(f"{output.label} is an input of this run ({source.what})")
            raise InputError(
                f"{output.label} would add a frame to {source.path}, an input of this run "
                f"({source.what})"
            )
    if output.names is not None:
        parts = _inside(source_path, path)
        if parts is not None and len(parts) == 1 and output.names.fullmatch(parts[0]):
            raise InputError(
                f"{output.label} would write over {source.path}, an input of this run "
                f"({source.what})"
            )


def _check_apart(first: Output, second: Output) -> None:
    a, b = _resolved(first.path), _resolved(second.path)
    if a == b or _same_existing(first.path, second.path):
        raise InputError(f"{first.label} and {second.label} are the same path; give each its own")
    for outer, inner, outer_path, inner_path in ((first, second, a, b), (second, first, b, a)):
        parts = _inside(inner_path, outer_path)
        if parts is None:
            continue
        if not outer.folder:
            raise InputError(f"{inner.label} lies inside {outer.label}, a file this run writes")
        if outer.names is not None and len(parts) == 1 and outer.names.fullmatch(parts[0]):
            raise InputError(f"{inner.label} would be overwritten by the frames of {outer.label}")
