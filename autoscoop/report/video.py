"""Write frames as an MP4 (H.264, plays in browsers) and as a small looping GIF for READMEs."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from autoscoop.core.safe_files import atomic_output

GIF_WIDTH_PX = 480
"""Width of the README GIF, pixels (height keeps the aspect ratio)."""
GIF_FPS = 8.0
"""Frame rate of the README GIF; every few frames of the video are kept."""


def write_mp4(frames: Sequence[np.ndarray], path: str | Path, fps: float) -> Path:
    """Encode RGB frames (all the same size, sides multiples of 16) as H.264 MP4 at ``fps``."""
    import imageio.v2 as imageio  # noqa: PLC0415 - optional dependency (extra "media")

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with imageio.get_writer(path, fps=fps, codec="libx264", quality=7, pixelformat="yuv420p",
                            macro_block_size=16, ffmpeg_log_level="error") as writer:
        for frame in frames:
            writer.append_data(np.asarray(frame))
    return path


def write_gif(frames: Sequence[np.ndarray], path: str | Path, fps: float, gif_fps: float = GIF_FPS,
              width: int = GIF_WIDTH_PX) -> Path:
    """A looping GIF of the frames, shrunk to ``width`` and thinned to about ``gif_fps``."""
    from PIL import Image  # noqa: PLC0415 - Pillow comes with imageio

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    keep = max(1, int(round(fps / gif_fps)))
    chosen = list(frames[::keep])
    if len(frames) and (len(frames) - 1) % keep:
        chosen.append(frames[-1])  # always end on the final state
    images = []
    for frame in chosen:
        image = Image.fromarray(np.asarray(frame))
        height = int(round(image.height * width / image.width))
        images.append(image.resize((width, height), Image.LANCZOS).quantize(colors=128))
    duration_ms = int(round(1000.0 * keep / fps))
    durations = [duration_ms] * (len(images) - 1) + [1500]  # linger on the result before looping
    with atomic_output(path) as tmp:  # a failed write leaves the previous file
        images[0].save(tmp, save_all=True, append_images=images[1:], duration=durations, loop=0,
                       optimize=True)
    return path
