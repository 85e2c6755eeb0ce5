"""Episode animations: GIF (Pillow) and MP4 (ffmpeg, where installed)."""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np

from socialnav.trajectory import Trajectory
from socialnav.viz.draw import FrameRenderer, frame_indices
from socialnav.viz.routes import Routes


class FfmpegMissingError(RuntimeError):
    """MP4 output needs the ``ffmpeg`` program."""


def frames(
    traj: Trajectory,
    *,
    overlays: Sequence[str] = (),
    stride: int = 1,
    max_frames: int | None = 400,
    size_px: tuple[int, int] = (560, 560),
    progress: bool = False,
    routes: Routes = True,
) -> Iterator[np.ndarray]:
    """RGB frames (H, W, 3) of the episode, one per shown sample (``routes``: as ``plot_trajectory``'s)."""
    renderer = FrameRenderer(traj, overlays=overlays, size_px=size_px, routes=routes)
    idx = frame_indices(renderer.view.n_samples, stride, max_frames)
    from tqdm.auto import tqdm

    for k in tqdm(idx, desc="frames", unit="frame", disable=not progress, leave=False):
        yield renderer.frame(k)


def _frame_ms(traj: Trajectory, stride_used: int, speed: float) -> int:
    if speed <= 0:
        raise ValueError(f"speed must be > 0, got {speed}")
    return max(20, int(round(1000 * traj.dt * stride_used / speed)))


def write_gif(
    traj: Trajectory,
    path: str | Path,
    *,
    overlays: Sequence[str] = (),
    stride: int = 1,
    max_frames: int | None = 400,
    speed: float = 1.0,
    size_px: tuple[int, int] = (560, 560),
    progress: bool = False,
    routes: Routes = True,
) -> int:
    """Writes an animated GIF (atomically); returns the number of frames.

    ``speed`` multiplies real time (1.0: one simulated second per second); ``routes``: the agents' routes
    around the walls, as :func:`socialnav.viz.draw.plot_trajectory` takes them.
    """
    from PIL import Image

    from socialnav._io import atomic_write

    n = FrameRenderer.n_samples_of(traj)
    idx = frame_indices(n, stride, max_frames)
    step = idx[1] - idx[0] if len(idx) > 1 else 1
    images = [
        Image.fromarray(f).quantize(colors=128, method=Image.Quantize.MEDIANCUT)
        for f in frames(
            traj, overlays=overlays, stride=stride, max_frames=max_frames, size_px=size_px, progress=progress,
            routes=routes,
        )
    ]
    duration = _frame_ms(traj, step, speed)

    def write(tmp: str) -> None:
        images[0].save(
            tmp,
            format="GIF",
            save_all=True,
            append_images=images[1:],
            duration=duration,
            loop=0,
            optimize=False,
        )

    atomic_write(Path(path), write)
    return len(images)


def ffmpeg_path() -> str | None:
    """The ffmpeg to use: ``$SOCIALNAV_FFMPEG``, else the one on PATH, else None."""
    return os.environ.get("SOCIALNAV_FFMPEG") or shutil.which("ffmpeg")


def write_mp4(
    traj: Trajectory,
    path: str | Path,
    *,
    overlays: Sequence[str] = (),
    stride: int = 1,
    max_frames: int | None = 400,
    speed: float = 1.0,
    size_px: tuple[int, int] = (560, 560),
    progress: bool = False,
    routes: Routes = True,
) -> int:
    """Writes an H.264 MP4 through ffmpeg (atomically); returns the number of frames.

    ``routes``: the agents' routes around the walls, as :func:`socialnav.viz.draw.plot_trajectory`
    takes them.

    Raises:
        FfmpegMissingError: ffmpeg is not installed (the message says how to get it, or to use GIF).
    """
    from socialnav._io import atomic_write

    exe = ffmpeg_path()
    if exe is None:
        raise FfmpegMissingError(
            "MP4 output needs ffmpeg, which is not installed or not on PATH (Debian/Ubuntu: "
            "apt-get install ffmpeg; or set SOCIALNAV_FFMPEG); use --format gif instead"
        )
    n = FrameRenderer.n_samples_of(traj)
    idx = frame_indices(n, stride, max_frames)
    step = idx[1] - idx[0] if len(idx) > 1 else 1
    fps = 1000.0 / _frame_ms(traj, step, speed)
    w, h = (s - s % 2 for s in size_px)  # yuv420p needs even sizes
    count = 0

    def write(tmp: str) -> None:
        nonlocal count
        cmd = [
            exe,
            "-loglevel",
            "error",
            "-y",
            "-f",
            "rawvideo",
            "-pix_fmt",
            "rgb24",
            "-s",
            f"{w}x{h}",
            "-r",
            f"{fps:.6g}",
            "-i",
            "-",
            "-c:v",
            "libx264",
            "-pix_fmt",
            "yuv420p",
            "-f",
            "mp4",
            tmp,
        ]
        proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
        try:
            for frame in frames(
                traj,
                overlays=overlays,
                stride=stride,
                max_frames=max_frames,
                size_px=(w, h),
                progress=progress,
                routes=routes,
            ):
                proc.stdin.write(np.ascontiguousarray(frame[:h, :w]).tobytes())
                count += 1
            proc.stdin.close()
        except BrokenPipeError:
            pass
        err = proc.stderr.read().decode(errors="replace")
        if proc.wait() != 0:
            raise RuntimeError(f"ffmpeg failed (exit {proc.returncode}): {err.strip()[-500:]}")

    atomic_write(Path(path), write)
    return count
