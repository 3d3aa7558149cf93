"""VideoReader: frame numbering, sizes, RGB order and clear errors (video files and folders)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from jaxtrack.errors import FileFormatError, InputError
from jaxtrack.io.video import VideoReader

WIDTH, HEIGHT, NUM_FRAMES = 32, 24, 10


def synthetic_frame(index: int) -> np.ndarray:
    """RGB frame ``index`` (from 0): red encodes the index, a green square marks top-left."""
    frame = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    frame[:, :, 0] = 20 * index + 10
    frame[:, :, 2] = 200 - 10 * index
    frame[:8, :8, 1] = 255
    return frame


def write_video(path: Path, num_frames: int = NUM_FRAMES, fps: float = 5.0) -> list[np.ndarray]:
    """Writes a lossless (FFV1) AVI and returns its RGB frames."""
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), fps, (WIDTH, HEIGHT))
    assert writer.isOpened()
    frames = [synthetic_frame(i) for i in range(num_frames)]
    for frame in frames:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    writer.release()
    return frames


@pytest.fixture(scope="module")
def vtest(data_root) -> Path:
    return data_root / "video" / "vtest.avi"


def test_vtest_is_pets09_s2l1_sized(vtest):
    with VideoReader(vtest) as reader:
        assert (reader.num_frames, reader.width, reader.height) == (795, 768, 576)
        assert reader.fps == pytest.approx(10.0)
    assert VideoReader(vtest, fps=7).fps == 7


def test_vtest_frame_numbers_match_decoding_order(vtest):
    capture = cv2.VideoCapture(str(vtest))
    decoded = []
    for _ in range(121):
        ok, image = capture.read()
        assert ok
        decoded.append(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))
    capture.release()
    assert not np.array_equal(decoded[0], decoded[120])
    with VideoReader(vtest) as reader:
        first = reader.read(1)
        assert first.dtype == np.uint8 and first.shape == (576, 768, 3)
        np.testing.assert_array_equal(first, decoded[0])
        # a seek forward, a step, a seek backward
        np.testing.assert_array_equal(reader.read(120), decoded[119])
        np.testing.assert_array_equal(reader.read(121), decoded[120])
        np.testing.assert_array_equal(reader.read(2), decoded[1])
        assert reader.read(795).shape == (576, 768, 3)
        for frame in (0, 796):
            with pytest.raises(FileFormatError, match=rf"frame {frame} outside 1\.\.795"):
                reader.read(frame)


def test_tiny_video_reads_every_frame_in_any_order(tmp_path):
    path = tmp_path / "tiny.avi"
    frames = write_video(path)
    with VideoReader(path) as reader:
        assert (reader.num_frames, reader.width, reader.height) == (NUM_FRAMES, WIDTH, HEIGHT)
        assert reader.fps == pytest.approx(5.0)
        for frame in [3, 4, 10, 1, 7, 7, 2]:
            np.testing.assert_array_equal(reader.read(frame), frames[frame - 1])
        assert reader.read(np.int64(5))[0, 0, 1] == 255  # RGB: green square stays green
    with pytest.raises(FileFormatError, match="closed"):
        reader.read(1)


def test_image_folder_in_natural_order(tmp_path):
    frames = [synthetic_frame(i) for i in range(11)]
    for i, frame in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"{i + 1}.png"), cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    (tmp_path / "notes.txt").write_text("not an image")
    reader = VideoReader(tmp_path, fps=25)
    assert (reader.num_frames, reader.width, reader.height, reader.fps) == (11, 32, 24, 25)
    for frame in (1, 2, 10, 11):  # 10.png after 9.png, not after 1.png
        np.testing.assert_array_equal(reader.read(frame), frames[frame - 1])
    assert VideoReader(tmp_path).fps is None
    with pytest.raises(FileFormatError, match=r"frame 12 outside 1\.\.11"):
        reader.read(12)


def test_image_folder_errors(tmp_path):
    with pytest.raises(FileFormatError, match="holds no"):
        VideoReader(tmp_path)
    cv2.imwrite(str(tmp_path / "000001.jpg"), synthetic_frame(0))
    cv2.imwrite(str(tmp_path / "000002.jpg"), np.zeros((10, 10, 3), np.uint8))
    (tmp_path / "000003.jpg").write_bytes(b"\xff\xd8 this is not really a jpeg")
    reader = VideoReader(tmp_path)
    with pytest.raises(FileFormatError, match=r"000002\.jpg: image is 10x10 but frame 1 is 32x24"):
        reader.read(2)
    with pytest.raises(FileFormatError, match=r"000003\.jpg: not an image"):
        reader.read(3)


def test_missing_corrupt_and_truncated_videos(tmp_path):
    with pytest.raises(FileFormatError, match="not found"):
        VideoReader(tmp_path / "missing.avi")
    junk = tmp_path / "junk.avi"
    junk.write_bytes(np.random.default_rng(0).bytes(5000))
    with pytest.raises(FileFormatError, match=r"junk\.avi: not a video file"):
        VideoReader(junk)
    empty = tmp_path / "empty.mp4"
    empty.write_bytes(b"")
    with pytest.raises(FileFormatError, match=r"empty\.mp4"):
        VideoReader(empty)

    whole = tmp_path / "whole.avi"
    write_video(whole)
    data = whole.read_bytes()
    cut = tmp_path / "cut.avi"
    cut.write_bytes(data[: len(data) * 3 // 4])
    with pytest.raises(FileFormatError, match=r"cut\.avi: .*(no decodable|does not decode)"):
        with VideoReader(cut) as reader:
            for frame in range(1, reader.num_frames + 1):
                reader.read(frame)


def test_bad_arguments(tmp_path, vtest):
    with pytest.raises(InputError, match=r"fps must lie in \[1, 1000\]"):
        VideoReader(vtest, fps=0)
    with pytest.raises(InputError, match="fps"):
        VideoReader(vtest, fps=float("nan"))
    with VideoReader(vtest) as reader, pytest.raises(InputError, match="must be an integer"):
        reader.read(1.5)
