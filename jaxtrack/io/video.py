"""Random access to the frames of a video file or an image folder (OpenCV).

Frames are addressed by their 1-based MOTChallenge number: frame ``k`` is the ``k``-th
decoded video frame (``k - 1`` counting from 0, as in ``vtest.avi`` = PETS09-S2L1) or the
``k``-th image of a folder in natural name order (``000001.jpg``, ``000002.jpg``, ...).
Frames come back as RGB ``uint8`` arrays ``[height, width, 3]``. Every problem with the
file (missing, unreadable, not a video, a frame that does not decode, a frame number out of
range) raises :class:`~jaxtrack.errors.FileFormatError` naming the file.
"""

from __future__ import annotations

import math
import numbers
import re
import warnings
from pathlib import Path

import cv2
import numpy as np

from jaxtrack.errors import FileFormatError, InputError, InputWarning
from jaxtrack.limits import FRAME_COUNT, FRAME_RATE, IMAGE_SIZE, MAX_FRAMES
from jaxtrack.types import SequenceInfo

#: File extensions (lower case) of the images an image folder may hold.
IMAGE_EXTENSIONS = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")

#: Reading forward by decoding is cheaper than seeking for gaps up to this many frames.
MAX_DECODE_AHEAD = 32


class VideoReader:
    """Frames of a video file or an image folder, by 1-based frame number.

    Use as a context manager (or call :meth:`close`) to release the video file.

    Args:
        path: a video file OpenCV can decode, or a folder of images.
        fps: frames per second to report instead of the file's own rate (an image folder
            has none).

    Attributes:
        path: the file or folder.
        num_frames: number of frames; valid frame numbers are ``1..num_frames``.
        width: frame width in pixels.
        height: frame height in pixels.
        fps: frames per second (the override, else the video's), or None when unknown.

    Raises:
        FileFormatError: the path does not exist, is not a decodable video, holds no frames
            or more than :data:`~jaxtrack.limits.MAX_FRAMES`, has frames outside the image-size
            rule (``16..65536`` pixels a side), or (folder) holds no images or an unreadable
            first image.
        InputError: ``fps`` breaks the frame-rate rule (``[1, 1000]``).

    Warns:
        InputWarning: the video's own frame rate breaks the frame-rate rule; it is then
            unknown (None).
    """

    def __init__(self, path: str | Path, fps: float | None = None):
        self.path = Path(path)
        if fps is not None:
            fps = FRAME_RATE.check("fps", fps)
        self._capture: cv2.VideoCapture | None = None
        self._bgr: np.ndarray | None = None  # the video's decode buffer, reused frame to frame
        self._images: list[Path] = []
        self._next_index = 0
        if self.path.is_dir():
            self._images = _image_files(self.path)
            if not self._images:
                raise FileFormatError(
                    self.path, None, f"image folder holds no {'/'.join(IMAGE_EXTENSIONS)} files"
                )
            self.num_frames = len(self._images)
            self.height, self.width = _decode_image(self._images[0]).shape[:2]
            self.fps = fps
            self._check_size()
        elif self.path.is_file():
            self._open_video()
            self._check_size()
            self.fps = fps if fps is not None else self._video_fps()
        else:
            raise FileFormatError(self.path, None, "video file or image folder not found")

    def _open_video(self) -> None:
        capture = cv2.VideoCapture(str(self.path))
        if not capture.isOpened():
            capture.release()
            raise FileFormatError(self.path, None, "not a video file OpenCV can open")
        self._capture = capture
        ok, first = capture.read()
        if not ok or first is None:
            self.close()
            raise FileFormatError(self.path, None, "video holds no decodable frame")
        self.height, self.width = first.shape[:2]
        reported = capture.get(cv2.CAP_PROP_FRAME_COUNT)
        count = int(reported) if math.isfinite(reported) and reported <= MAX_FRAMES + 1 else -1
        if count <= 0:
            count = 1
            while count <= MAX_FRAMES and capture.grab():
                count += 1
        self.num_frames = count
        capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
        self._next_index = 0

    def _check_size(self) -> None:
        """The frame count and frame size rules (:mod:`jaxtrack.limits`)."""
        for key, value, rule in (
            ("number of frames", self.num_frames, FRAME_COUNT),
            ("frame width", self.width, IMAGE_SIZE),
            ("frame height", self.height, IMAGE_SIZE),
        ):
            try:
                rule.check(key, int(value))
            except InputError as err:
                self.close()
                raise FileFormatError(self.path, None, str(err)) from None

    def _video_fps(self) -> float | None:
        rate = float(self._capture.get(cv2.CAP_PROP_FPS))
        if rate == 0:
            return None
        try:
            return FRAME_RATE.check("frame rate", rate)
        except InputError as err:
            warnings.warn(
                InputWarning(f"{self.path}: ignoring the video's {err}; give --fps"),
                stacklevel=3,
            )
            return None

    def read(self, frame: int, out: np.ndarray | None = None) -> np.ndarray:
        """Returns one frame.

        Args:
            frame: 1-based frame number.
            out: an RGB ``uint8`` ``[height, width, 3]`` array to decode the frame into
                (a video file is then read without allocating: a stream reading many frames
                reuses its arrays), or None for a new array.

        Returns:
            The frame, RGB ``uint8``, ``[height, width, 3]`` (``out`` when given).

        Raises:
            FileFormatError: ``frame`` outside ``1..num_frames``, the reader is closed, the
                frame does not decode, or (folder) its image has another size than frame 1.
            InputError: ``frame`` is not an integer, or ``out`` not a C-contiguous ``uint8``
                array of the frame's shape.
        """
        if isinstance(frame, bool) or not isinstance(frame, numbers.Integral):
            raise InputError(f"frame must be an integer, got {frame!r}")
        frame = int(frame)
        if not 1 <= frame <= self.num_frames:
            raise FileFormatError(
                self.path, None, f"frame {frame} outside 1..{self.num_frames} (frames it holds)"
            )
        if out is not None and (
            out.dtype != np.uint8
            or out.shape != (self.height, self.width, 3)
            or not out.flags.c_contiguous
        ):
            raise InputError(
                f"out must be a C-contiguous uint8 array of shape {(self.height, self.width, 3)}"
                f", got {out.dtype} {out.shape}"
            )
        if self._images:
            return self._read_image(frame - 1, out)
        return self._read_video(frame - 1, out)

    def _read_video(self, index: int, out: np.ndarray | None) -> np.ndarray:
        if self._capture is None:
            raise FileFormatError(self.path, None, "video reader is closed")
        capture = self._capture
        if not 0 <= index - self._next_index <= MAX_DECODE_AHEAD:
            capture.set(cv2.CAP_PROP_POS_FRAMES, index)
            self._next_index = index
        while self._next_index < index:
            if not capture.grab():
                break
            self._next_index += 1
        ok, image = capture.read(self._bgr) if self._next_index == index else (False, None)
        if not ok or image is None or image.shape[:2] != (self.height, self.width):
            self._next_index = -MAX_DECODE_AHEAD - 1
            raise FileFormatError(
                self.path, None, f"frame {index + 1} of {self.num_frames} does not decode"
            )
        self._bgr = image
        self._next_index = index + 1
        return _to_rgb(image, out)

    def _read_image(self, index: int, out: np.ndarray | None) -> np.ndarray:
        path = self._images[index]
        image = _decode_image(path)
        if image.shape[:2] != (self.height, self.width):
            raise FileFormatError(
                path,
                None,
                f"image is {image.shape[1]}x{image.shape[0]} but frame 1 is "
                f"{self.width}x{self.height}",
            )
        return _to_rgb(image, out)

    def close(self) -> None:
        """Releases the video file; reading afterwards raises FileFormatError."""
        if self._capture is not None:
            self._capture.release()
            self._capture = None

    def __enter__(self) -> VideoReader:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"VideoReader({str(self.path)!r}, num_frames={self.num_frames}, "
            f"size={self.width}x{self.height}, fps={self.fps})"
        )


def _image_files(folder: Path) -> list[Path]:
    """The folder's image files in natural order (``2.jpg`` before ``10.jpg``)."""
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_EXTENSIONS]

    def natural_key(path: Path) -> list:
        return [(0, int(part), "") if part.isdigit() else (1, 0, part) for part in _split(path)]

    return sorted(files, key=natural_key)


def _split(path: Path) -> list[str]:
    return [part for part in re.split(r"(\d+)", path.name) if part]


def _decode_image(path: Path) -> np.ndarray:
    """An image file as OpenCV's BGR ``uint8`` array.

    Raises:
        FileFormatError: the file cannot be read or is no image OpenCV decodes.
    """
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as err:
        raise FileFormatError(path, None, f"cannot read image: {err.strerror}") from None
    image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
    if image is None:
        raise FileFormatError(path, None, "not an image OpenCV can decode")
    return image


def _to_rgb(image: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """OpenCV's BGR ``uint8`` image as RGB (written into ``out`` when given)."""
    if out is None:
        return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
    cv2.cvtColor(image, cv2.COLOR_BGR2RGB, dst=out)
    return out


#: Video files a sequence folder may hold as ``<name><extension>``.
VIDEO_EXTENSIONS = (".mp4", ".avi")


def find_frame_source(
    sequence_dir: str | Path, name: str, video: str | Path | None = None
) -> Path | None:
    """The frames of a MOTChallenge sequence: ``video`` if given, else ``img1/``, else
    ``<name>.mp4`` / ``<name>.avi`` in the folder, else None."""
    if video is not None:
        return Path(video)
    sequence_dir = Path(sequence_dir)
    if (sequence_dir / "img1").is_dir():
        return sequence_dir / "img1"
    for extension in VIDEO_EXTENSIONS:
        candidate = sequence_dir / f"{name}{extension}"
        if candidate.is_file():
            return candidate
    return None


def open_sequence_frames(
    sequence_dir: str | Path, info: SequenceInfo, video: str | Path | None = None
) -> VideoReader:
    """Opens the frames of a MOTChallenge sequence (:func:`find_frame_source`) and checks
    them against its ``seqinfo.ini``: as many frames as ``seqLength``, of ``imWidth`` x
    ``imHeight`` pixels (frame ``k`` of the reader is then MOT frame ``k``).

    Args:
        sequence_dir: the sequence folder.
        info: its sequence information.
        video: a video file or image folder to use instead of the folder's own frames.

    Returns:
        The open reader (the caller closes it).

    Raises:
        InputError: no frames found (naming the paths looked for).
        FileFormatError: frames that do not open, or whose count or size differ from
            ``seqinfo.ini``'s.
    """
    source = find_frame_source(sequence_dir, info.name, video)
    if source is None:
        folder = Path(sequence_dir)
        looked = ", ".join(str(folder / f"{info.name}{ext}") for ext in VIDEO_EXTENSIONS)
        raise InputError(
            f"no frames for {folder}: looked for {folder / 'img1'}/ and {looked}; "
            "give a video file or image folder (--video)"
        )
    reader = VideoReader(source, fps=info.frame_rate)
    found = (reader.num_frames, reader.width, reader.height)
    if found != (info.seq_length, info.im_width, info.im_height):
        reader.close()
        raise FileFormatError(
            source,
            None,
            f"holds {found[0]} frames of {found[1]}x{found[2]} but {info.name}'s seqinfo.ini "
            f"says {info.seq_length} frames of {info.im_width}x{info.im_height}",
        )
    return reader


#: Codec of written ``.mp4`` / ``.avi`` files (MPEG-4 part 2, in every OpenCV build).
WRITER_FOURCC = "mp4v"
#: Frame rate of written videos when the source has none.
DEFAULT_WRITE_FPS = 7.0


class FrameWriter:
    """Writes RGB frames to a video file (``.mp4`` / ``.avi``) or a folder of PNG images.

    A path ending in ``.mp4`` or ``.avi`` is a video file; any other path is a folder that
    receives ``000001.png``, ``000002.png``, ... (numbered by the frame numbers given).
    Use as a context manager (or call :meth:`close`).

    Args:
        path: the video file or PNG folder.
        size: ``(width, height)`` of every frame.
        fps: frames per second of a video file (default :data:`DEFAULT_WRITE_FPS`).

    Raises:
        FileFormatError: OpenCV cannot open the video file for writing.
    """

    def __init__(self, path: str | Path, size: tuple[int, int], fps: float | None = None):
        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        self._video = None
        self.path.parent.mkdir(parents=True, exist_ok=True)
        if self.path.suffix.lower() in VIDEO_EXTENSIONS:
            fourcc = cv2.VideoWriter_fourcc(*WRITER_FOURCC)
            self._video = cv2.VideoWriter(
                str(self.path), fourcc, fps or DEFAULT_WRITE_FPS, self.size
            )
            if not self._video.isOpened():
                raise FileFormatError(self.path, None, "OpenCV cannot write this video file")
        else:
            self.path.mkdir(parents=True, exist_ok=True)

    def write(self, image: np.ndarray, frame: int) -> None:
        """Appends an RGB ``uint8`` ``[height, width, 3]`` image (PNG: named by ``frame``).

        Raises:
            InputError: the image is not of the writer's size.
        """
        if image.shape[:2] != (self.size[1], self.size[0]):
            raise InputError(
                f"frame is {image.shape[1]}x{image.shape[0]}, writer expects "
                f"{self.size[0]}x{self.size[1]}"
            )
        bgr = cv2.cvtColor(image, cv2.COLOR_RGB2BGR)
        if self._video is not None:
            self._video.write(bgr)
        elif not cv2.imwrite(str(self.path / f"{frame:06d}.png"), bgr):
            raise FileFormatError(self.path, None, f"cannot write frame {frame} as PNG")

    def close(self) -> None:
        """Finishes the video file."""
        if self._video is not None:
            self._video.release()
            self._video = None

    def __enter__(self) -> FrameWriter:
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()


def id_colour(track_id: int) -> tuple[int, int, int]:
    """A distinct, stable RGB colour per id (golden-ratio hue steps)."""
    hue = int((track_id * 0.618033988749895 % 1.0) * 180)
    hsv = np.uint8([[[hue, 220, 255]]])
    return tuple(int(c) for c in cv2.cvtColor(hsv, cv2.COLOR_HSV2RGB)[0, 0])


def annotate_frame(
    image: np.ndarray,
    boxes: np.ndarray,
    ids: np.ndarray | None = None,
    trails: dict[int, np.ndarray] | None = None,
    overlay: np.ndarray | None = None,
    label: str | None = None,
) -> np.ndarray:
    """Draws boxes (by id colour), trails and an optional intensity overlay on a frame.

    Args:
        image: RGB ``uint8`` ``[height, width, 3]`` (not modified).
        boxes: ``(x, y, w, h)``, ``[num_boxes, 4]``.
        ids: id of each box; None draws detections (white, thin) without labels.
        trails: per id, the ``[num_points, 2]`` image points of its recent path (drawn as a
            polyline in the id's colour).
        overlay: ``[height, width]`` non-negative intensity blended in as a heat map
            (scaled by its maximum).
        label: text in the top-left corner (e.g. the frame number).

    Returns:
        The annotated copy.
    """
    out = image.copy()
    if overlay is not None:
        peak = float(np.max(overlay)) if overlay.size else 0.0
        if peak > 0:
            heat = cv2.applyColorMap(
                np.uint8(np.clip(overlay / peak, 0, 1) * 255), cv2.COLORMAP_INFERNO
            )
            out = cv2.addWeighted(out, 0.6, cv2.cvtColor(heat, cv2.COLOR_BGR2RGB), 0.4, 0)
    for track_id, points in (trails or {}).items():
        if len(points) > 1:
            cv2.polylines(
                out, [np.round(points).astype(np.int32)], False, id_colour(int(track_id)), 2
            )
    for k, (x, y, w, h) in enumerate(np.asarray(boxes, np.float64).reshape(-1, 4).tolist()):
        top_left = (round(x), round(y))
        bottom_right = (round(x + w), round(y + h))
        if ids is None:
            cv2.rectangle(out, top_left, bottom_right, (255, 255, 255), 1)
            continue
        colour = id_colour(int(ids[k]))
        cv2.rectangle(out, top_left, bottom_right, colour, 2)
        cv2.putText(
            out,
            str(int(ids[k])),
            (top_left[0], top_left[1] - 3),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.5,
            colour,
            1,
            cv2.LINE_AA,
        )
    if label:
        cv2.putText(out, label, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.7, (255, 255, 0), 2)
    return out
