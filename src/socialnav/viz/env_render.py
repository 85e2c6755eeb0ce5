"""The Gymnasium env's viewer.

A frame is the same drawing as an episode animation's (viz.draw.FrameRenderer) of the episode so far;
``human`` mode shows it in a matplotlib window.

Registered with :func:`socialnav.envs.render.register_viewer` by the package root, so that the
simulator never imports this package (docs/internals.md, "Layers").
"""

from __future__ import annotations

from typing import Any

import numpy as np


class EnvViewer:
    """Draws the env's episode so far; ``show`` keeps one window open across calls."""

    def __init__(self, size_px: tuple[int, int] = (480, 480)):
        self.size_px = size_px
        self._window: Any = None

    def frame(self, trajectory: Any) -> np.ndarray:
        """The episode drawn at its last sample: (H, W, 3) uint8."""
        from socialnav.viz.draw import FrameRenderer

        renderer = FrameRenderer(trajectory, size_px=self.size_px, overlays=("personal_space",))
        return renderer.frame(trajectory.n_steps)

    def show(self, trajectory: Any, fps: float) -> None:
        """Show the episode drawn at its last sample in a matplotlib window, paced at ``fps``."""
        import matplotlib.pyplot as plt

        image = self.frame(trajectory)
        if self._window is None or not plt.fignum_exists(self._window[0].number):
            plt.ion()
            fig, ax = plt.subplots(figsize=(self.size_px[0] / 100, self.size_px[1] / 100))
            ax.axis("off")
            self._window = (fig, ax.imshow(image))
        else:
            self._window[1].set_data(image)
        plt.pause(1.0 / fps)

    def close(self) -> None:
        """Close the window, if one is open."""
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
