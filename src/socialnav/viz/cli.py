"""`socialnav render` and `socialnav report` argument parsing and commands (matplotlib imported lazily)."""

from __future__ import annotations

import argparse
import math
import re
import sys
import warnings
from pathlib import Path
from typing import Any

from socialnav.logs.command import add_layout_arguments, add_map_arguments, layout_from_args, map_from_args

FORMATS = ("png", "svg", "gif", "mp4", "html")


def add_viz_parsers(sub: argparse._SubParsersAction) -> None:
    """Add the ``render`` and ``report`` subcommands to ``sub``."""
    rd = sub.add_parser(
        "render",
        help="draw one episode: plot (png/svg), animation (gif/mp4) or a viewer page (html)",
        description="Draws one episode of an evaluation's result directory (stored trajectories) or of "
        "a trajectory file (docs/trajectory_format.md).",
    )
    rd.add_argument(
        "source", help="result directory of `socialnav evaluate`, or a .parquet/.csv trajectory file"
    )
    rd.add_argument(
        "--episode",
        help="episode id: <scenario>/<visibility>/<index> in a result directory, the episode key in a file "
        "(optional when the file holds one episode)",
    )
    rd.add_argument("--format", choices=FORMATS, help="default: from --out's suffix, else png")
    rd.add_argument("--out", help="output file (default: <result dir>/renders/<scenario>_<visibility>_<index>"
                    ".<format>; for a trajectory file ./<episode key>.<format>)")
    rd.add_argument(
        "--overlay",
        nargs="+",
        default=[],
        help="metric geometry: personal_space (M_I), velocity_rectangles (M_II), side_preference (M_VI), "
        "lidar (the robot's scan: its world's lidar, else 360 beams, 10 m), all",
    )
    rd.add_argument("--every", type=int, help="plots: steps between time-stamped discs (default ~8 stamps)")
    rd.add_argument("--stride", type=int, default=1, help="animations: show every n-th sample (default 1)")
    rd.add_argument("--max-frames", type=int, default=400,
                    help="animations: at most this many frames (default 400)")
    rd.add_argument("--speed", type=float, default=1.0,
                    help="animations: playback speed x real time (default 1)")
    rd.add_argument("--eps", type=float, default=0.2, help="M_I threshold of the overlay [m] (default 0.2)")
    rd.add_argument("--tau", type=float, default=1.0, help="M_II horizon of the overlay [s] (default 1)")
    rd.add_argument("--resample", action="store_true", help="files: resample irregular timestamps")
    rd.add_argument(
        "--routes",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="among walls, draw each routed agent's route planned at its start, dashed: the humans' where "
        "the episode's world set human_routes, the robot's under orca_route/social_force_route "
        "(default: on; only where routes exist)",
    )
    # A robot log in another layout is read as `socialnav metrics` reads it (docs/real_world_logs.md).
    add_layout_arguments(rd)
    rd.add_argument("--ego", help="draw agent ID of a pedestrian log as the robot")
    add_map_arguments(
        rd,
        "draw the walls of this map file (YAML or SVG, docs/walls_maps.md) instead of "
        "the map stored with the episode, if any",
    )
    rd.add_argument("--quiet", action="store_true", help="no progress bar, no message")
    rd.set_defaults(run=_run_render)

    rp = sub.add_parser(
        "report",
        help="one self-contained HTML report (tables, figures, settings, interactive episode viewer)",
        description="Writes one HTML file that opens without network access: the paper's tables, metric "
        "figures, every setting and threshold, and an episode viewer. Several result directories "
        "(one per policy) are compared in one report.",
    )
    rp.add_argument("results", nargs="+", help="result directories of `socialnav evaluate`")
    rp.add_argument("--out", help="HTML file (default <first result directory>/report.html)")
    rp.add_argument("--curves", nargs="*", default=[], help="training curves.csv files to plot")
    rp.add_argument(
        "--viewer-episodes",
        type=int,
        default=3,
        help="episodes per (policy, scenario, visibility) in the viewer, picked best/median/worst by a "
        "metric (default 3; 0: no viewer)",
    )
    rp.add_argument("--no-figure-files", action="store_true", help="do not also write figures/*.png|svg")
    rp.add_argument("--quiet", action="store_true", help="no progress bar, no message")
    rp.set_defaults(run=_run_report)


def _safe(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "episode"


def load_source(source: str | Path, episode: str | None, resample: bool = False, **log: Any):
    """(trajectory, default output directory) from a result directory or a trajectory file.

    ``log``: how to read a robot log of another layout (``columns``, ``robot``, ``ego``, ``radius``,
    ``time_unit``, ``length_unit``, as :func:`socialnav.logs.load_trajectories` takes them).
    """
    from socialnav.trajectory import read_trajectories

    path = Path(source)
    if path.is_dir():
        from socialnav.evaluate.results import list_episodes, load_episode

        if episode is None:
            ids = list_episodes(path)
            shown = ", ".join(ids[:5]) + (", ..." if len(ids) > 5 else "")
            raise ValueError(f"{path}: pass --episode <scenario>/<visibility>/<index> (stored: {shown})")
        return load_episode(path, episode), path / "renders"
    if not path.exists():
        raise FileNotFoundError(f"{path}: no such result directory or trajectory file")
    from socialnav.logs.loading import detect_format

    given = {k: v for k, v in log.items() if v is not None and (k, v) not in (("time_unit", "s"),
                                                                              ("length_unit", "m"))}
    if given or detect_format(path) != "long":
        # A robot log in another layout (no radius column, other column names, ETH/UCY): read as
        # `socialnav metrics` reads it, with the same assumed values and warnings.
        return _one_log_episode(path, episode, resample, **given), Path(".")
    trajs = read_trajectories(path, resample=resample, episodes=None if episode is None else [episode])
    if not trajs:
        keys = [str(t.settings.get("episode")) for t in read_trajectories(path, resample=resample)]
        raise ValueError(
            f"{path}: no episode {episode!r}; episodes in the file: {', '.join(keys[:20])}"
            + (", ..." if len(keys) > 20 else "")
        )
    if len(trajs) > 1:
        keys = [str(t.settings.get("episode")) for t in trajs]
        raise ValueError(
            f"{path} holds {len(trajs)} episodes: pass --episode KEY "
            f"(one of {', '.join(keys[:20])}{', ...' if len(keys) > 20 else ''})"
        )
    return trajs[0], Path(".")


def _one_log_episode(path: Path, episode: str | None, resample: bool, **log: Any):
    from socialnav.logs.loading import load_trajectories

    if str(log.get("ego", "")).lower() == "all":
        raise ValueError("--ego all: render draws one episode; give one agent id")
    trajs = load_trajectories(path, resample=resample, **log)

    def key(t) -> str:
        return str(t.settings.get("episode", t.settings.get("scene")))

    chosen = trajs if episode is None else [t for t in trajs if key(t) == str(episode)]
    keys = [key(t) for t in trajs]
    shown = ", ".join(keys[:20]) + (", ..." if len(keys) > 20 else "")
    if not chosen:
        raise ValueError(f"{path}: no episode {episode!r}; episodes in the file: {shown}")
    if len(chosen) > 1:
        raise ValueError(f"{path} holds {len(chosen)} episodes: pass --episode KEY (one of {shown})")
    return chosen[0]


def _routes(traj, source: str) -> dict:
    """The routes drawn with ``traj``; from a result directory, the robot's as its manifest records."""
    from socialnav.viz.routes import episode_routes

    manifest = None
    if Path(source).is_dir():
        from socialnav.evaluate.results import load_manifest

        manifest = load_manifest(source)
    return episode_routes(traj, manifest)


def _run_render(args: argparse.Namespace) -> int:
    from socialnav.viz import require_viz
    from socialnav.viz.geometry import parse_overlays

    require_viz()
    overlays = parse_overlays(args.overlay)
    for flag, value in (("--eps", args.eps), ("--tau", args.tau)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{flag} must be a finite number > 0, got {value}")
    for flag, value in (("--every", args.every), ("--max-frames", args.max_frames)):
        if value is not None and value < 1:
            raise ValueError(f"{flag} must be an integer >= 1, got {value}")
    fmt = args.format
    suffix = Path(args.out).suffix.lower().lstrip(".") if args.out else ""
    if fmt is None:
        if suffix and suffix not in FORMATS:
            raise ValueError(f"--out {args.out}: cannot write .{suffix}; formats: {', '.join(FORMATS)}")
        fmt = suffix or "png"
    if args.out and suffix not in ("", fmt):
        raise ValueError(f"--out {args.out} does not end in .{fmt} (the --format)")
    if fmt == "html" and overlays:
        # the page's viewer has its own switches (trails, M_I, M_II, M_VI) and no lidar
        raise ValueError(f"--overlay {' '.join(args.overlay)}: the html page draws no --overlay (its viewer "
                         "switches the metric overlays itself and has no lidar); use --format png, svg, gif "
                         "or mp4")
    smap = map_from_args(args)
    log = {**layout_from_args(args), "ego": args.ego}
    with warnings.catch_warnings(record=True) as caught:  # said as `socialnav metrics` says them
        warnings.simplefilter("always")
        traj, default_dir = load_source(args.source, args.episode, args.resample, **log)
    for note in dict.fromkeys(str(w.message) for w in caught):
        if not args.quiet:
            print(f"note: {note}", file=sys.stderr)
    routes = _routes(traj, args.source) if args.routes else False  # planned on the episode's own walls
    if smap is not None:
        import dataclasses

        traj = dataclasses.replace(traj, static_map=smap)
    name = _safe(str(traj.settings.get("episode", "episode")))
    out = Path(args.out) if args.out else default_dir / f"{name}.{fmt}"
    blocking = next((p for p in [out.parent, *out.parent.parents] if p.is_file()), None)
    if blocking is not None:
        raise ValueError(f"--out {out}: {blocking} is a file, not a directory")
    out.parent.mkdir(parents=True, exist_ok=True)
    progress = not args.quiet
    detail = ""
    if fmt in ("png", "svg"):
        from socialnav._io import atomic_write
        from socialnav.viz.draw import plot_trajectory

        fig = plot_trajectory(traj, overlays=overlays, every=args.every, eps=args.eps, tau=args.tau,
                              routes=routes)
        atomic_write(out, lambda tmp: fig.savefig(tmp, format=fmt))
    elif fmt in ("gif", "mp4"):
        from socialnav.viz.animate import write_gif, write_mp4

        writer = write_gif if fmt == "gif" else write_mp4
        n = writer(
            traj,
            out,
            overlays=overlays,
            stride=args.stride,
            max_frames=args.max_frames,
            speed=args.speed,
            progress=progress,
            routes=routes,
        )
        detail = f" ({n} frames)"
    else:
        from socialnav._io import atomic_write_text
        from socialnav.viz.report import episode_page

        atomic_write_text(out, episode_page(traj, eps=args.eps, tau=args.tau, routes=routes))
    if not args.quiet:
        print(f"wrote {out}{detail}", file=sys.stderr)
    return 0


def _run_report(args: argparse.Namespace) -> int:
    from socialnav.viz.report import write_report

    out = Path(args.out) if args.out else Path(args.results[0]) / "report.html"
    info = write_report(
        [Path(r) for r in args.results],
        out,
        curves=[Path(c) for c in args.curves],
        viewer_episodes=args.viewer_episodes,
        figure_files=not args.no_figure_files,
        progress=not args.quiet,
    )
    if not args.quiet:
        print(
            f"wrote {out} ({info['bytes'] / 1e6:.2f} MB, {info['viewer_episodes']} episodes in the viewer)",
            file=sys.stderr,
        )
    return 0
