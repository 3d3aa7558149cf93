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
from pathlib import Path

import cv2
import numpy as np

from jaxtrack.errors import FileFormatError, InputError

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
        FileFormatError: the path does not exist, is not a decodable video, holds no frames,
            or (folder) holds no images or an unreadable first image.
        InputError: ``fps`` is not a positive finite number.
    """

    def __init__(self, path: str | Path, fps: float | None = None):
        self.path = Path(path)
        if fps is not None and not (math.isfinite(fps) and fps > 0):
            raise InputError(f"fps must be a positive number, got {fps}")
        self._capture: cv2.VideoCapture | None = None
        self._images: list[Path] = []
        self._next_index = 0
        if self.path.is_dir():
            self._images = _image_files(self.path)
            if not self._images:
                raise FileFormatError(
                    self.path, None, f"image folder holds no {'/'.join(IMAGE_EXTENSIONS)} files"
                )
            self.num_frames = len(self._images)
            self.height, self.width = self._read_image(0).shape[:2]
            self.fps = fps
        elif self.path.is_file():
            self._open_video()
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
        count = int(capture.get(cv2.CAP_PROP_FRAME_COUNT))
        if count <= 0:
            count = 1
            while capture.grab():
                count += 1
        self.num_frames = count
        capture.set(cv2.CAP_PROP_POS_FRAMES, 0)
        self._next_index = 0

    def _video_fps(self) -> float | None:
        rate = float(self._capture.get(cv2.CAP_PROP_FPS))
        return rate if math.isfinite(rate) and rate > 0 else None

    def read(self, frame: int) -> np.ndarray:
        """Returns one frame.

        Args:
            frame: 1-based frame number.

        Returns:
            The frame, RGB ``uint8``, ``[height, width, 3]``.

        Raises:
            FileFormatError: ``frame`` outside ``1..num_frames``, the reader is closed, the
                frame does not decode, or (folder) its image has another size than frame 1.
            InputError: ``frame`` is not an integer.
        """
        if isinstance(frame, bool) or not isinstance(frame, numbers.Integral):
            raise InputError(f"frame must be an integer, got {frame!r}")
        frame = int(frame)
        if not 1 <= frame <= self.num_frames:
            raise FileFormatError(
                self.path, None, f"frame {frame} outside 1..{self.num_frames} (frames it holds)"
            )
        if self._images:
            image = self._read_image(frame - 1)
            if image.shape[:2] != (self.height, self.width):
                raise FileFormatError(
                    self._images[frame - 1],
                    None,
                    f"image is {image.shape[1]}x{image.shape[0]} but frame 1 is "
                    f"{self.width}x{self.height}",
                )
            return image
        return self._read_video(frame - 1)

    def _read_video(self, index: int) -> np.ndarray:
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
        ok, image = capture.read() if self._next_index == index else (False, None)
        if not ok or image is None:
            self._next_index = -MAX_DECODE_AHEAD - 1
            raise FileFormatError(
                self.path, None, f"frame {index + 1} of {self.num_frames} does not decode"
            )
        self._next_index = index + 1
        return _to_rgb(image)

    def _read_image(self, index: int) -> np.ndarray:
        path = self._images[index]
        try:
            data = np.fromfile(path, dtype=np.uint8)
        except OSError as err:
            raise FileFormatError(path, None, f"cannot read image: {err.strerror}") from None
        image = cv2.imdecode(data, cv2.IMREAD_COLOR) if data.size else None
        if image is None:
            raise FileFormatError(path, None, "not an image OpenCV can decode")
        return _to_rgb(image)

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


def _to_rgb(image: np.ndarray) -> np.ndarray:
    """OpenCV's BGR ``uint8`` image as RGB."""
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)


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
