"""Rendering of the single Gymnasium env (``render_mode="rgb_array"`` or ``"human"``).

The env hands this recorder its observations (the terminal one included, before the auto-reset
slot is refilled); a frame is the same drawing as an episode animation's (viz.draw.FrameRenderer)
of the episode so far.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from socialnav.sim.observation import HUMAN_PX, HUMAN_PY, ROBOT_PX, ROBOT_PY

RENDER_MODES = ("rgb_array", "human")


def available_render_modes() -> list[str]:
    """``rgb_array`` always; ``human`` only where a display exists (Gymnasium's checker tries each)."""
    return ["rgb_array", "human"] if has_display() else ["rgb_array"]


def check_render_mode(mode: str | None) -> None:
    if mode is not None and mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be one of {', '.join(RENDER_MODES)} or None, got {mode!r}")
    if mode is not None:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            raise RuntimeError(
                f"render_mode={mode!r} needs matplotlib: pip install 'socialnav[viz]'"
            ) from None
    if mode == "human" and not has_display():
        raise RuntimeError(
            "render_mode='human' needs a display (no DISPLAY or WAYLAND_DISPLAY is set); "
            "use render_mode='rgb_array' and save the frames (e.g. with socialnav.viz.animate)"
        )


def has_display() -> bool:
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class EnvRecorder:
    """Positions of the current episode, collected from the env's observations."""

    def __init__(self, size_px: tuple[int, int] = (480, 480)):
        self.size_px = size_px
        self.positions: list[np.ndarray] = []
        self.outcome = "unknown"
        self._window = None

    def start(self, world, obs: dict[str, np.ndarray], index: int) -> None:
        agents = np.flatnonzero(world.mask[0])
        self.agents = agents
        self.radii = world.radius[0, agents].copy()
        self.goals = world.goal[0, agents].copy()
        self.v_pref = world.v_pref[0, agents].copy()
        self.dt = world.settings.dt
        self.index = index
        self.scenario = getattr(world.scenario, "name", "")
        self.positions = []
        self.outcome = "unknown"
        self.record(obs)

    def record(self, obs: dict[str, np.ndarray], outcome: str = "running") -> None:
        robot = obs["robot"][[ROBOT_PX, ROBOT_PY]]
        humans = obs["humans"][:, [HUMAN_PX, HUMAN_PY]][self.agents[1:] - 1]
        self.positions.append(np.vstack([robot[None], humans]))
        if outcome not in ("running", ""):
            self.outcome = outcome

    def frame(self) -> np.ndarray:
        """The episode so far, drawn at its last sample: (H, W, 3) uint8."""
        from socialnav.trajectory import Trajectory
        from socialnav.viz.draw import FrameRenderer

        traj = Trajectory.from_positions(
            np.stack(self.positions),
            self.dt,
            radii=self.radii,
            v_pref=self.v_pref,
            goals=self.goals,
            outcome=self.outcome if self.outcome in ("success", "collision", "timeout") else "unknown",
            settings={"episode": f"{self.scenario} #{self.index}"},
        )
        renderer = FrameRenderer(traj, size_px=self.size_px, overlays=("personal_space",))
        return renderer.frame(traj.n_steps)

    def show(self, fps: float) -> None:
        import matplotlib.pyplot as plt

        image = self.frame()
        if self._window is None or not plt.fignum_exists(self._window[0].number):
            plt.ion()
            fig, ax = plt.subplots(figsize=(self.size_px[0] / 100, self.size_px[1] / 100))
            ax.axis("off")
            self._window = (fig, ax.imshow(image))
        else:
            self._window[1].set_data(image)
        plt.pause(1.0 / fps)

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
