"""Writing frames to an mp4, with the writer gymnasium's ``RecordVideo`` uses (moviepy,
which drives ffmpeg through imageio-ffmpeg): one dependency for every echogym video."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

__all__ = ["VIDEO_EXTRA", "write_mp4"]

#: What to install for videos.
VIDEO_EXTRA = "pip install 'echogym[video]'"


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, fps: float) -> Path:
    """Write uint8 ``(h, w, 3)`` frames as an H.264 mp4 at ``fps``; the path.

    Raises:
        ImportError: moviepy is not installed (the message names the extra).
        ValueError: no frames, or frames of different shapes.
    """
    try:
        from moviepy.video.io.ImageSequenceClip import ImageSequenceClip
    except ImportError as exc:
        raise ImportError(f"echogym's videos need moviepy: {VIDEO_EXTRA}") from exc
    if not frames:
        raise ValueError(f"{path}: no frames to write")
    shapes = {np.shape(f) for f in frames}
    if len(shapes) != 1:
        raise ValueError(f"{path}: frames of different shapes {sorted(shapes)}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    clip = ImageSequenceClip([np.asarray(f, dtype=np.uint8) for f in frames], fps=fps)
    # Write next to the target and rename, so a failed encode leaves no half-written file.
    partial = path.with_name(f".{path.stem}.partial{path.suffix}")
    try:
        clip.write_videofile(str(partial), codec="libx264", audio=False, logger=None)
        partial.replace(path)
    finally:
        partial.unlink(missing_ok=True)
        clip.close()
    return path
