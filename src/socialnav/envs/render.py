"""Rendering of the single Gymnasium env (``render_mode="rgb_array"`` or ``"human"``).

The modes and the recording of the episode; the drawing is a viewer registered from above.

The env hands the recorder its observations (the terminal one included, before the auto-reset slot
is refilled). Drawing needs the ``viz`` extra and sits above the simulator (socialnav.viz), so the
simulator does not import it: a viewer factory is registered with :func:`register_viewer` (the
package root registers :class:`socialnav.viz.env_render.EnvViewer`, which draws the same frame as
an episode animation's, viz.draw.FrameRenderer, of the episode so far).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any, Protocol

import numpy as np

from socialnav.sim.observation import HUMAN_PX, HUMAN_PY, ROBOT_PX, ROBOT_PY

RENDER_MODES = ("rgb_array", "human")


class Viewer(Protocol):
    """Draws an episode so far (a :class:`~socialnav.trajectory.Trajectory`) for the env."""

    def frame(self, trajectory: Any) -> np.ndarray:
        """The episode drawn at its last sample: (H, W, 3) uint8."""

    def show(self, trajectory: Any, fps: float) -> None:
        """Show the episode drawn at its last sample in a window, at ``fps`` frames per second."""

    def close(self) -> None:
        """Close the viewer's window, if any."""


_VIEWER_FACTORY: Callable[[tuple[int, int]], Viewer] | None = None


def register_viewer(factory: Callable[[tuple[int, int]], Viewer]) -> None:
    """Sets what draws the env's frames: ``factory(size_px)`` returns a :class:`Viewer`."""
    global _VIEWER_FACTORY
    _VIEWER_FACTORY = factory


def available_render_modes() -> list[str]:
    """``rgb_array`` always; ``human`` only where a display exists (Gymnasium's checker tries each)."""
    return ["rgb_array", "human"] if has_display() else ["rgb_array"]


def check_render_mode(mode: str | None) -> None:
    """Check ``render_mode`` and that what it needs is available.

    Raises:
        ValueError: Unknown mode.
        RuntimeError: matplotlib is missing, or ``human`` mode has no display.
    """
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
    """Whether a window can be shown (macOS, Windows, or ``$DISPLAY``/``$WAYLAND_DISPLAY`` set)."""
    if sys.platform in ("darwin", "win32"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


class EnvRecorder:
    """Positions of the current episode, collected from the env's observations."""

    def __init__(self, size_px: tuple[int, int] = (480, 480)):
        self.size_px = size_px
        self.positions: list[np.ndarray] = []
        self.outcome = "unknown"
        self._viewer: Viewer | None = None

    def start(self, world, obs: dict[str, np.ndarray], index: int) -> None:
        """Start recording an episode from its first observation.

        Args:
            world: The env's world (one slot): radii, goals and v_pref of its agents.
            obs: The first observation (the env's dict).
            index: The episode's index in its split.
        """
        agents = np.flatnonzero(world.mask[0])
        self.agents = agents
        self.radii = world.radius[0, agents].copy()
        self.goals = world.goal[0, agents].copy()
        self.v_pref = world.v_pref[0, agents].copy()
        self.dt = world.settings.dt
        self.index = index
        self.scenario = getattr(world.scenario, "name", "")
        self.static_map = world.static_maps[0]  # the episode's walls (None: an open floor)
        self.positions = []
        self.outcome = "unknown"
        self.record(obs)

    def record(self, obs: dict[str, np.ndarray], outcome: str = "running") -> None:
        """Record one observation's positions, and the outcome once it is known."""
        robot = obs["robot"][[ROBOT_PX, ROBOT_PY]]
        humans = obs["humans"][:, [HUMAN_PX, HUMAN_PY]][self.agents[1:] - 1]
        self.positions.append(np.vstack([robot[None], humans]))
        if outcome not in ("running", ""):
            self.outcome = outcome

    def trajectory(self) -> Any:
        """The episode so far as a :class:`~socialnav.trajectory.Trajectory`."""
        from socialnav.trajectory import Trajectory

        return Trajectory.from_positions(
            np.stack(self.positions),
            self.dt,
            radii=self.radii,
            v_pref=self.v_pref,
            goals=self.goals,
            outcome=self.outcome if self.outcome in ("success", "collision", "timeout") else "unknown",
            settings={"episode": f"{self.scenario} #{self.index}"},
            static_map=self.static_map,
        )

    def frame(self) -> np.ndarray:
        """The episode so far, drawn at its last sample: (H, W, 3) uint8."""
        return self.viewer().frame(self.trajectory())

    def show(self, fps: float) -> None:
        """Show the episode so far in the viewer's window at ``fps`` frames per second."""
        self.viewer().show(self.trajectory(), fps)

    def close(self) -> None:
        """Close the viewer, if one was made."""
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

    def viewer(self) -> Viewer:
        """The registered viewer, made on first use.

        Raises:
            RuntimeError: No viewer is registered.
        """
        if self._viewer is None:
            if _VIEWER_FACTORY is None:
                raise RuntimeError("no viewer registered to draw the env (import socialnav registers one)")
            self._viewer = _VIEWER_FACTORY(self.size_px)
        return self._viewer
