"""Drawing episodes with matplotlib (Agg, no window): static plots and animation frames.

One set of conventions for every output (PNG/SVG plot, GIF/MP4 frames, the Gymnasium env's
``rgb_array``): the robot is black with a yellow fill, humans take the ``tab10`` colours, starts are
squares, goals stars, collisions red crosses.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from socialnav.trajectory import Trajectory
from socialnav.viz.geometry import EpisodeView, episode_view, parse_overlays, scene_bounds, velocity_rectangle
from socialnav.viz.routes import Routes, resolve_routes

ROBOT_FACE = "#ffd23f"
ROBOT_EDGE = "#111111"
VIOLATION = "#d62728"
_HUMAN_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#ff7f0e", "#7f7f7f")


WALL_FACE = "#9a9a9a"
WALL_EDGE = "#4a4a4a"
WALL_SEGMENT_PT = 4.0  # line width of a wall segment [points]: zero-thickness walls must stay visible


def draw_static_map(ax, smap) -> None:
    """Walls under everything else: solid polygons filled, wall segments as thick lines."""
    if smap is None:
        return
    from matplotlib.patches import Polygon

    for poly in smap.polygons:
        if poly.shape[0] == 2:
            ax.plot(poly[:, 0], poly[:, 1], "-", color=WALL_EDGE, lw=WALL_SEGMENT_PT, solid_capstyle="butt",
                    zorder=0.5)
        else:
            ax.add_patch(Polygon(poly, closed=True, facecolor=WALL_FACE, edgecolor=WALL_EDGE, lw=1.0,
                                 zorder=0.5))


ROUTE_STYLE = {"ls": "--", "lw": 0.9, "alpha": 0.6, "zorder": 0.8}  # thin, dashed, over walls, under agents


def draw_routes(ax, routes: dict[int, np.ndarray]) -> list:
    """Each route (:mod:`socialnav.viz.routes`) as a dashed line in its agent's colour; returns the lines."""
    return [ax.plot(line[:, 0], line[:, 1], color=agent_colour(a), **ROUTE_STYLE)[0]
            for a, line in sorted(routes.items())]


def agent_colour(agent: int) -> str:
    """Agent ``agent``'s colour: the robot's (agent 0), else one of a cycle of human colours."""
    return ROBOT_EDGE if agent == 0 else _HUMAN_COLOURS[(agent - 1) % len(_HUMAN_COLOURS)]


def new_figure(size_px: tuple[int, int] = (640, 640), dpi: int = 100):
    """A figure on the Agg canvas (never a window), whatever matplotlib's default backend is."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
    FigureCanvasAgg(fig)
    return fig


def figure_rgb(fig) -> np.ndarray:
    """The figure's pixels, (H, W, 3) uint8."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()


def _stamp_every(n_steps: int, dt: float) -> int:
    # about eight time stamps, on round times
    seconds = max(dt, n_steps * dt / 8)
    nice = min((s for s in (0.5, 1, 2, 2.5, 5, 10, 20, 30, 60) if s >= seconds), default=60)
    return max(1, int(round(nice / dt)))


def plot_trajectory(
    traj: Trajectory,
    *,
    overlays: Sequence[str] = (),
    every: int | None = None,
    title: str | None = None,
    eps: float = 0.2,
    tau: float = 1.0,
    size_px: tuple[int, int] = (720, 720),
    routes: Routes = True,
):
    """Static plot of one episode: paths, discs fading over time, time stamps every ``every`` steps.

    Args:
        traj: The episode.
        overlays: Metric geometry to add (see :mod:`socialnav.viz.geometry`).
        every: Steps between stamped discs (default: about eight stamps on round times).
        title: Axes title (default: the episode id, outcome and duration).
        eps: M_I's threshold ε [m] of the overlays.
        tau: M_II's time horizon τ [s] of the overlays.
        size_px: (width, height) of the figure [px].
        routes: The agents' routes around the walls, dashed (:mod:`socialnav.viz.routes`): True, those
            the trajectory records enough to plan; False, none; or routes already planned.

    Returns:
        A matplotlib Figure on the Agg canvas (save it with ``fig.savefig("x.png")`` or ``.svg``).
    """
    from matplotlib.patches import Circle, Polygon

    overlays = parse_overlays(overlays)
    view = episode_view(traj, eps, tau)
    fig = new_figure(size_px)
    ax = fig.add_subplot(1, 1, 1)
    K = traj.n_steps
    every = every or _stamp_every(K, traj.dt)
    stamps = sorted(set(range(0, K + 1, every)) | {K})
    pos = view.positions
    draw_static_map(ax, traj.static_map)
    if draw_routes(ax, resolve_routes(traj, routes)):
        ax.plot([], [], color="#555555", **ROUTE_STYLE, label="route planned at the start")
    for a in range(traj.n_agents):
        colour = agent_colour(a)
        ax.plot(pos[: view.n_main, a, 0], pos[: view.n_main, a, 1], "-", color=colour, lw=1.0, alpha=0.7)
        if view.n_samples > view.n_main:  # after the robot's arrival (visible runs, M_III)
            ax.plot(
                pos[view.n_main - 1 :, a, 0],
                pos[view.n_main - 1 :, a, 1],
                ":",
                color=colour,
                lw=0.8,
                alpha=0.5,
            )
        for k in stamps:
            if not np.isfinite(pos[k, a]).all():  # not in view then (a log's person who came or left)
                continue
            alpha = 0.15 + 0.75 * (k / K if K else 1.0)
            face = ROBOT_FACE if a == 0 else colour
            ax.add_patch(
                Circle(
                    tuple(pos[k, a]),
                    traj.radii[a],
                    facecolor=face,
                    edgecolor=colour,
                    alpha=alpha,
                    lw=1.2 if a == 0 else 0.6,
                )
            )
            if a == 0 or traj.n_agents <= 8:
                ax.annotate(
                    f"{k * traj.dt:g}",
                    tuple(pos[k, a]),
                    fontsize=7 if a == 0 else 6,
                    ha="center",
                    va="center",
                    color="black" if a == 0 else "white",
                    alpha=min(1, alpha + 0.2),
                )
        seen = np.flatnonzero(np.isfinite(traj.positions[:, a]).all(axis=1))
        if seen.size:  # where it was first seen
            ax.plot(*traj.positions[seen[0], a], "s", color=colour, ms=5, alpha=0.8)
        if np.isfinite(traj.goals[a]).all():
            ax.plot(*traj.goals[a], "*", color=colour, ms=11 if a == 0 else 7, alpha=0.9)
    hits = np.flatnonzero(view.collision)
    if hits.size:
        ax.plot(pos[hits, 0, 0], pos[hits, 0, 1], "x", color=VIOLATION, ms=12, mew=2.5, label="collision")
    if "personal_space" in overlays:
        # grey rings at the stamps, red ones at every flagged sample
        for k in sorted(set(stamps) | set(np.flatnonzero(view.m1).tolist())):
            flagged = bool(view.m1[k])
            ax.add_patch(
                Circle(
                    tuple(pos[k, 0]),
                    traj.radii[0] + eps,
                    fill=False,
                    ls="--",
                    lw=1.8 if flagged else 0.9,
                    edgecolor=VIOLATION if flagged else "#555555",
                    alpha=1.0 if flagged else 0.8,
                )
            )
        n = int(view.m1.sum())
        ax.plot([], [], "--", color=VIOLATION, label=f"M_I ε={eps:g} m: {n} sample(s) flagged")
    if "velocity_rectangles" in overlays:
        for k in stamps[1:]:
            for a in range(traj.n_agents):
                if not (np.isfinite(pos[k, a]).all() and np.isfinite(view.velocities[k, a]).all()):
                    continue  # not in view then
                rect = velocity_rectangle(pos[k, a], view.velocities[k, a], traj.radii[a], tau)
                if rect is None:
                    continue
                bad = bool(view.m2[k]) and a == 0
                ax.add_patch(
                    Polygon(
                        rect,
                        closed=True,
                        fill=bad,
                        alpha=0.25 if bad else 0.6,
                        facecolor=VIOLATION,
                        edgecolor=VIOLATION if bad else agent_colour(a),
                        lw=0.7,
                    )
                )
        ax.plot(
            [], [], "-", color=VIOLATION, label=f"M_II τ={tau:g} s: {int(view.m2.sum())} sample(s) flagged"
        )
    if "side_preference" in overlays:
        _draw_side(ax, view)
    if "lidar" in overlays:  # the scan at the robot's last sample (socialnav.viz.lidar)
        from socialnav.viz.lidar import draw_scan, lidar_of

        draw_scan(ax, view, view.n_main - 1)
        ax.plot([], [], ".", color="#2a9d8f", label=f"lidar ({lidar_of(traj)[0]} beams) at the end")
    x0, x1, y0, y1 = scene_bounds(traj)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.25)
    ax.set_title(title or describe_episode(traj), fontsize=10)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    return fig


def describe_episode(traj: Trajectory) -> str:
    """One line naming an episode: policy, episode id, outcome and duration [s]."""
    ep = traj.settings.get("episode", "")
    policy = traj.settings.get("policy")
    who = f"{policy} · " if policy else ""
    return f"{who}{ep} · {traj.outcome} · {traj.duration:g} s"


def _draw_side(ax, view: EpisodeView) -> None:
    if view.side is None:
        ax.plot([], [], " ", label="M_VI: not a single-human episode")
        return
    k, label = view.side
    p = view.positions[k, 0]
    ax.axhline(p[1], color="#444444", lw=0.8, ls="-.", alpha=0.7)  # Δy = 0 through the robot
    ax.annotate(
        "", xy=(p[0], p[1] + 1.0), xytext=tuple(p), arrowprops={"arrowstyle": "->", "color": "#444444"}
    )
    ax.annotate(
        "", xy=(p[0] + 1.0, p[1]), xytext=tuple(p), arrowprops={"arrowstyle": "->", "color": "#444444"}
    )
    ax.plot(*view.positions[k, 1], "o", mfc="none", mec=VIOLATION, ms=14)
    ax.text(
        0.02,
        0.02,
        f"M_VI: passes on the {label} (read at t = {k * view.traj.dt:g} s, dash-dot line: Δy = 0)"
        if label in ("left", "right")
        else f"M_VI: {label}",
        transform=ax.transAxes,
        fontsize=8,
        color="#222222",
        bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
    )


class FrameRenderer:
    """Draws sample k of an episode (for GIF/MP4); reuses one figure and its artists.

    ``routes``: as :func:`plot_trajectory`'s, drawn once under everything that moves.
    """

    def __init__(
        self,
        traj: Trajectory,
        *,
        overlays: Sequence[str] = (),
        eps: float = 0.2,
        tau: float = 1.0,
        size_px: tuple[int, int] = (560, 560),
        title: str | None = None,
        routes: Routes = True,
    ):
        from matplotlib.patches import Circle, Polygon

        self.view = episode_view(traj, eps, tau)
        self.traj, self.overlays = traj, parse_overlays(overlays)
        self.fig = new_figure(size_px)
        ax = self.ax = self.fig.add_subplot(1, 1, 1)
        x0, x1, y0, y1 = scene_bounds(traj)
        ax.set_xlim(x0, x1)
        ax.set_ylim(y0, y1)
        ax.set_aspect("equal")
        ax.grid(alpha=0.25)
        ax.set_title(title or describe_episode(traj), fontsize=9)
        draw_static_map(ax, traj.static_map)
        self.routes = draw_routes(ax, resolve_routes(traj, routes))
        for a in range(traj.n_agents):
            ax.plot(*traj.goals[a], "*", color=agent_colour(a), ms=10 if a == 0 else 7, alpha=0.8)
        self.trails = [
            ax.plot([], [], "-", color=agent_colour(a), lw=1.0, alpha=0.6)[0] for a in range(traj.n_agents)
        ]
        self.discs = [
            ax.add_patch(
                Circle(
                    (0, 0),
                    traj.radii[a],
                    facecolor=ROBOT_FACE if a == 0 else agent_colour(a),
                    edgecolor=agent_colour(a),
                    lw=1.5 if a == 0 else 0.8,
                    alpha=0.9,
                )
            )
            for a in range(traj.n_agents)
        ]
        self.ring = ax.add_patch(
            Circle(
                (0, 0),
                traj.radii[0] + eps,
                fill=False,
                ls="--",
                lw=1.0,
                visible="personal_space" in self.overlays,
            )
        )
        self.rects = [
            ax.add_patch(Polygon(np.zeros((4, 2)), closed=True, fill=False, lw=0.8, visible=False))
            for _ in range(traj.n_agents)
        ]
        self.cross = ax.plot([], [], "x", color=VIOLATION, ms=14, mew=3)[0]
        self.scan = None
        if "lidar" in self.overlays:  # the robot's scan of each frame (socialnav.viz.lidar)
            from socialnav.viz.lidar import draw_scan

            self.scan = draw_scan(ax, self.view, 0)
        self.clock = ax.text(
            0.02,
            0.97,
            "",
            transform=ax.transAxes,
            va="top",
            fontsize=10,
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
        )
        self.fig.tight_layout()

    @staticmethod
    def n_samples_of(traj: Trajectory) -> int:
        """Samples S of ``traj`` as drawn: main samples plus the continuation's."""
        return traj.positions.shape[0] + (0 if traj.continuation is None else traj.continuation.shape[0])

    def frame(self, k: int) -> np.ndarray:
        """Draw sample ``k`` (moving the artists) and return the frame: (H, W, 3) uint8."""
        v, traj = self.view, self.traj
        pos = v.positions
        for a in range(traj.n_agents):
            self.discs[a].center = tuple(pos[k, a])
            self.trails[a].set_data(pos[: k + 1, a, 0], pos[: k + 1, a, 1])
        if "personal_space" in self.overlays:
            self.ring.center = tuple(pos[k, 0])
            self.ring.set_edgecolor(VIOLATION if v.m1[k] else "#555555")
        for a, patch in enumerate(self.rects):
            rect = None
            if "velocity_rectangles" in self.overlays and k > 0:
                rect = velocity_rectangle(pos[k, a], v.velocities[k, a], traj.radii[a], v.tau)
            patch.set_visible(rect is not None)
            if rect is not None:
                patch.set_xy(rect)
                patch.set_edgecolor(VIOLATION if (a == 0 and v.m2[k]) else agent_colour(a))
        hits = np.flatnonzero(v.collision[: k + 1])
        self.cross.set_data(pos[hits, 0, 0], pos[hits, 0, 1])
        if self.scan is not None:
            from socialnav.viz.lidar import move_scan

            move_scan(self.scan, v, k)
        note = " (after arrival)" if k >= v.n_main else ""
        side = ""
        if "side_preference" in self.overlays and v.side is not None and k >= v.side[0]:
            side = f"\nM_VI: {v.side[1]}"
        self.clock.set_text(f"t = {k * traj.dt:.2f} s{note}{side}")
        return figure_rgb(self.fig)


def frame_indices(n_samples: int, stride: int = 1, max_frames: int | None = None) -> list[int]:
    """Samples shown in an animation: every ``stride``-th, thinned to ``max_frames``, last included."""
    if stride < 1:
        raise ValueError(f"stride must be >= 1, got {stride}")
    if max_frames is not None and max_frames >= 2:
        stride = max(stride, math.ceil((n_samples - 1) / (max_frames - 1)))
    idx = list(range(0, n_samples, stride))
    if idx[-1] != n_samples - 1:
        idx.append(n_samples - 1)
    return idx
