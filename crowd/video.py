"""Moving pictures: a run's frames as an H.264 MP4 (``crowd run --video``, ``[output] video = true``).

Frames are piped to the ffmpeg binary that the ``imageio-ffmpeg`` wheel ships (no system ffmpeg needed) and encoded
with libx264 into yuv420p, the pixel format every player decodes. yuv420p stores chroma at half resolution, so both
sides must be even: an odd width or height is padded by repeating the last column / row (the picture's top-left
``w x h`` pixels are the frame; the MP4 is one pixel wider or taller).

Atomic like every output: the encoder writes ``.<name>.tmp-<pid>.mp4`` beside the final file, which is renamed to
``<name>`` only after ffmpeg has finished; on any error the partial file is removed. In a run the final file is
inside the run's temporary folder, which itself appears only when the run has finished (``crowd.output``).
"""
from __future__ import annotations

import os
from contextlib import contextmanager
from pathlib import Path

import numpy as np

#: file name of a run's video, beside ``frames/``
VIDEO_NAME = "video.mp4"
#: x264 constant rate factor (0 = lossless .. 51; 12 keeps a frame within ~35 dB PSNR of its PNG, yuv420p chroma
#: being the rest) and preset of run videos
CRF = 12
PRESET = "veryfast"
#: the clips ``crowd report`` embeds per setting: small and short (x264 options of :class:`VideoWriter`)
REPORT_CLIP = {"max_width": 480, "crf": 28, "max_frames": 150, "threads": 1}
#: ffmpeg's accepted frame-rate range
FPS_RANGE = (1.0, 240.0)


def ffmpeg_exe() -> str:
    """Path of imageio-ffmpeg's ffmpeg binary; a one-sentence ``crowd.errors.CrowdError`` when missing."""
    from crowd.errors import CrowdError

    try:
        import imageio_ffmpeg
    except ImportError:
        raise CrowdError("video: needs the Python package imageio-ffmpeg (pip install imageio-ffmpeg; "
                         "a runtime dependency of crowd-sandbox)") from None
    try:
        return imageio_ffmpeg.get_ffmpeg_exe()
    except RuntimeError as e:
        raise CrowdError(f"video: imageio-ffmpeg found no ffmpeg binary ({e})") from None


def even_size(size) -> tuple:
    """(width, height) rounded up to even numbers (yuv420p)."""
    w, h = (int(v) for v in size)
    return w + (w & 1), h + (h & 1)


def pad_even(pixels: np.ndarray) -> np.ndarray:
    """``pixels`` (h, w, 3) uint8 with the last column / row repeated where w / h is odd."""
    h, w = pixels.shape[:2]
    if not (h & 1 or w & 1):
        return pixels
    return np.pad(pixels, ((0, h & 1), (0, w & 1), (0, 0)), mode="edge")


class VideoWriter:
    """An MP4 written frame by frame; appears at ``path`` only after :meth:`close`.

    Parameters
    ----------
    path : final file
    size : (width, height) of the frames given to :meth:`write` (odd sides are padded)
    fps : frames per second (clamped to :data:`FPS_RANGE`)
    crf, preset : x264 quality and speed
    max_width : scale the picture down to at most this width (even height kept; None: full size)
    max_frames : keep only the first frames (later :meth:`write` calls are ignored; None: all)
    threads : encoder threads (None: ffmpeg's choice; 1 keeps a timed run's other core free)
    """

    def __init__(self, path, size, fps: float, crf: int = CRF, preset: str = PRESET, max_width: int | None = None,
                 max_frames: int | None = None, threads: int | None = None):
        import imageio_ffmpeg

        ffmpeg_exe()
        self.path = Path(path)
        self.size = (int(size[0]), int(size[1]))
        self.tmp = self.path.with_name(f".{self.path.stem}.tmp-{os.getpid()}{self.path.suffix or '.mp4'}")
        fps = min(FPS_RANGE[1], max(FPS_RANGE[0], float(fps)))
        params = ["-crf", str(int(crf)), "-preset", preset, "-movflags", "+faststart"]
        if threads:
            params += ["-threads", str(int(threads))]
        if max_width and self.size[0] > max_width:
            params += ["-vf", f"scale={int(max_width) // 2 * 2}:-2"]
        self.frames = 0
        self.max_frames = max_frames
        self._gen = imageio_ffmpeg.write_frames(str(self.tmp), even_size(self.size), fps=fps, codec="libx264",
                                                pix_fmt_in="rgb24", pix_fmt_out="yuv420p", quality=None,
                                                macro_block_size=1, ffmpeg_log_level="error",
                                                output_params=params)
        self._gen.send(None)  # starts ffmpeg

    @property
    def accepting(self) -> bool:
        """False once ``max_frames`` frames were written (the caller may skip reading the next ones back)."""
        return self._gen is not None and (self.max_frames is None or self.frames < self.max_frames)

    def write(self, pixels: np.ndarray) -> None:
        """Append one frame, (h, w, 3) uint8 top row first, of this writer's size."""
        if self.max_frames is not None and self.frames >= self.max_frames:
            return
        px = np.asarray(pixels)
        if px.dtype != np.uint8 or px.shape != (self.size[1], self.size[0], 3):
            raise ValueError(f"video {self.path}: expected ({self.size[1]}, {self.size[0]}, 3) uint8 pixels, "
                             f"got {px.shape} {px.dtype}")
        self._gen.send(np.ascontiguousarray(pad_even(px)).tobytes())
        self.frames += 1

    def close(self) -> Path:
        """Finish encoding and move the file into place; returns its path."""
        gen, self._gen = self._gen, None
        if gen is not None:
            gen.close()
            os.replace(self.tmp, self.path)
        return self.path

    def abort(self) -> None:
        """Stop ffmpeg and remove the partial file (safe twice)."""
        gen, self._gen = self._gen, None
        try:
            if gen is not None:
                gen.close()
        except Exception:  # the error being handled matters more than ffmpeg's complaint
            pass
        finally:
            self.tmp.unlink(missing_ok=True)


@contextmanager
def video_writer(path, size, fps: float, enabled: bool = True, **kw):
    """A :class:`VideoWriter` closed (moved into place) on success and aborted on any exception, KeyboardInterrupt
    included; yields None when not ``enabled``."""
    if not enabled:
        yield None
        return
    w = VideoWriter(path, size, fps, **kw)
    try:
        yield w
    except BaseException:
        w.abort()
        raise
    try:
        w.close()
    except BaseException:
        w.abort()
        raise


def read_video(path) -> tuple:
    """(frames (n, h, w, 3) uint8, (width, height)) of a video decoded by imageio-ffmpeg (tests, reports)."""
    import imageio_ffmpeg

    gen = imageio_ffmpeg.read_frames(str(path))
    meta = gen.__next__()
    w, h = (int(v) for v in meta["size"])
    frames = [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in gen]
    return (np.stack(frames) if frames else np.zeros((0, h, w, 3), np.uint8)), (w, h)
