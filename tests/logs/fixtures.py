"""Synthetic pedestrian scenes in the ETH/UCY text format, written by the tests (no downloads)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

FPS = 25.0
FRAME_STEP = 10  # 0.4 s, 2.5 Hz as in the ETH/UCY annotations


def pedestrian_scene(seed: int = 0, n: int = 10, frames: int = 60) -> dict[int, np.ndarray]:
    """Pedestrians crossing a 12 m square at 1.0–1.5 m/s, entering at staggered frames.

    Returns ``{id: (m, 3) array of (frame, x, y)}``. Lanes are spaced so that nobody comes closer
    than about 1 m (positive clearances with 0.3 m radii), with a small lateral sway.
    """
    rng = np.random.default_rng(seed)
    tracks = {}
    for i in range(n):
        speed = rng.uniform(1.0, 1.5)
        direction = 1.0 if i % 2 == 0 else -1.0
        horizontal = i % 4 < 2
        lane = -5.0 + 2.0 * (i // 2) + (1.0 if direction < 0 else 0.0)
        start = int(rng.integers(0, frames // 3))
        length = int(rng.integers(frames // 3, frames - start))
        k = np.arange(length)
        s = -6.0 * direction + direction * speed * k * FRAME_STEP / FPS
        sway = 0.05 * np.sin(0.8 * k + i)
        x, y = (s, lane + sway) if horizontal else (lane + 40.0 + sway, s)  # two groups far apart
        tracks[100 + i] = np.stack([(start + k) * FRAME_STEP + 780, x, y], axis=1)
    return tracks


def write_eth_ucy(path: Path, tracks: dict[int, np.ndarray]) -> Path:
    """Write tracks as ``frame<TAB>id<TAB>x<TAB>y`` lines sorted by frame, as the Social-GAN copies."""
    rows = [(f, pid, x, y) for pid, tr in tracks.items() for f, x, y in tr]
    rows.sort(key=lambda r: (r[0], r[1]))
    path.write_text("".join(f"{f:.1f}\t{pid:.1f}\t{x:.4f}\t{y:.4f}\n" for f, pid, x, y in rows))
    return path
