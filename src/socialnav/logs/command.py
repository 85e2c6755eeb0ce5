"""The ``socialnav metrics`` subcommand (kept here, apart from the rest of the CLI).

Exit status: 0 scored cleanly (notes about assumed values may be printed), 1 scored but the data
raised warnings (inconsistent outcome labels, agents skipped, social metrics NaN for unknown
outcomes), 2 nothing scored: the input is wrong (one line naming file, column and row).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from typing import TYPE_CHECKING, Any

from socialnav._io import json_safe
from socialnav.logs.loading import FORMATS
from socialnav.logs.readers import ETH_UCY_FPS, FIELDS, MAX_SPEED

if TYPE_CHECKING:
    from socialnav.maps.static_map import StaticMap

EXIT_WARNINGS = 1
EXIT_ERROR = 2
_PER_EPISODE_LIMIT = 10


def add_metrics_parser(sub: Any) -> None:
    """Add the ``metrics`` subcommand to ``sub``."""
    me = sub.add_parser(
        "metrics",
        help="score trajectory files: robot logs, or pedestrians as the robot (ETH/UCY, any CSV/Parquet)",
        description="Score robot logs or pedestrian data with every metric. Formats: long (the project's "
        "schema, docs/trajectory_format.md), csv/parquet with any columns (--columns), eth-ucy "
        "('frame id x y' text). See docs/real_world_logs.md.",
    )
    me.add_argument("file", nargs="+", help="trajectory file(s); several files are scenes of one dataset")
    me.add_argument("--format", choices=FORMATS, default="auto",
                    help="default auto: .txt -> eth-ucy; .csv/.parquet with the long schema's columns -> "
                    "long, else csv/parquet")
    me.add_argument("--ego", help="score agent ID (or 'all': every non-robot agent in turn) as the robot, "
                    "from its observed start to its observed end ('human as robot')")
    add_layout_arguments(me)
    me.add_argument("--dt", type=float, help="time step to score at [s] (default: the data's median step)")
    me.add_argument("--resample", action="store_true",
                    help="long format: interpolate irregular timestamps (other formats always do, with a "
                    "note)")
    me.add_argument("--max-gap", type=float, help="longest gap in a track bridged by interpolation [s] "
                    "(default: twice each agent's own median step when resampling; on a regular clock, "
                    "missing samples stay absent unless it is given)")
    me.add_argument("--fps", type=float, default=ETH_UCY_FPS,
                    help=f"eth-ucy: frame numbers per second (default {ETH_UCY_FPS:g}: 10 frames = 0.4 s)")
    me.add_argument("--max-speed", type=float, default=MAX_SPEED,
                    help=f"reject faster steps as implausible [m/s] (default {MAX_SPEED:g}; 'inf' disables)")
    me.add_argument("--goal-tolerance", type=float,
                    help="a 'success' ending farther than this from its goal is reported [m] (default: "
                    "the robot's radius)")
    add_map_arguments(me, "static map (YAML or SVG, docs/walls_maps.md) of every episode: the obstacle "
                      "clearance metrics use it; replaces a map stored in the file (with a note)")
    me.add_argument("--all-episodes", action="store_true",
                    help="score social metrics on every episode, not only successful ones (logs)")
    me.add_argument("--per-episode", action="store_true",
                    help=f"print every episode (default: only when there are <= {_PER_EPISODE_LIMIT})")
    me.add_argument("--json", action="store_true", help="print one JSON object")
    me.add_argument("--quiet", action="store_true", help="print no notes (warnings and errors still show)")
    me.set_defaults(run=cmd_metrics)


def add_layout_arguments(parser: Any) -> None:
    """Add how a log of another layout is read: ``--columns``, ``--robot``, ``--radius`` and the units.

    ``socialnav metrics`` and ``socialnav render`` share them (:func:`layout_from_args` reads them), so
    that a log is read the same way by both.

    Args:
        parser: The subcommand's parser.
    """
    parser.add_argument("--columns", help="csv/parquet column mapping FIELD=COLUMN,... with FIELD in: "
                        + ", ".join(FIELDS))
    parser.add_argument("--robot", help="csv/parquet: id of the robot (default: the agent with role 'robot')")
    parser.add_argument("--radius", type=float, help="radius of every agent when the file has none [m] "
                        "(default 0.3, with a note)")
    parser.add_argument("--length-unit", choices=["m", "cm", "mm"], default="m",
                        help="csv/parquet: of positions, radii, goals, and speeds (per second; default m)")
    parser.add_argument("--time-unit", choices=["s", "ms", "us", "ns"], default="s",
                        help="csv/parquet: of the time column (default s)")


def layout_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """The keywords of :func:`socialnav.logs.load_trajectories` that :func:`add_layout_arguments` gave."""
    return {"columns": args.columns, "robot": args.robot, "radius": args.radius,
            "length_unit": args.length_unit, "time_unit": args.time_unit}


def add_map_arguments(parser: Any, map_help: str) -> None:
    """Add ``--map FILE`` and ``--map-scale M_PER_UNIT``, which :func:`map_from_args` reads.

    ``socialnav metrics`` and ``socialnav render`` share them, so that a map file means the same to both.

    Args:
        parser: The subcommand's parser.
        map_help: The help of ``--map``: what the command does with the map.
    """
    parser.add_argument("--map", metavar="FILE", help=map_help)
    parser.add_argument(
        "--map-scale",
        type=float,
        metavar="M_PER_UNIT",
        help="SVG maps: metres per SVG user unit (default: the file's data-scale, else 1)",
    )


def map_from_args(args: argparse.Namespace) -> StaticMap | None:
    """The map of ``--map`` read at ``--map-scale``, or None without ``--map``.

    Args:
        args: A command line parsed with :func:`add_map_arguments`'s arguments.

    Returns:
        The map, or None when no ``--map`` is given.

    Raises:
        ValueError: ``--map-scale`` without ``--map``, or not a finite number > 0; a
            :class:`~socialnav.maps.files.MapFileError` for the map file itself.
    """
    from socialnav.maps.files import load_map

    scale = args.map_scale
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"--map-scale must be a finite number > 0, got {scale}")
    if args.map is None:
        if scale is not None:
            raise ValueError("--map-scale needs --map")
        return None
    return load_map(args.map, scale=scale)


def cmd_metrics(args: argparse.Namespace) -> int:
    """``socialnav metrics``: score trajectory files with every metric.

    Args:
        args: The parsed command line.

    Returns:
        The exit status.
    """
    import warnings

    from socialnav.logs.loading import DataWarning, load_trajectories
    from socialnav.logs.scoring import score_trajectories

    notes: list[str] = []
    problems: list[str] = []
    if args.dt is not None and not (math.isfinite(args.dt) and args.dt > 0):
        print(f"socialnav metrics: error: --dt must be > 0 and finite, got {args.dt}", file=sys.stderr)
        return EXIT_ERROR
    try:
        smap = map_from_args(args)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            trajs = []
            for path in args.file:
                loaded = load_trajectories(
                    path, format=args.format, ego=args.ego, dt=args.dt, resample=args.resample,
                    max_gap=args.max_gap, fps=args.fps, max_speed=args.max_speed, **layout_from_args(args),
                )
                if not loaded:
                    raise ValueError(f"{path}: no episodes (the file has a header but no rows)")
                trajs += loaded
            if smap is not None:
                trajs = _with_map(trajs, args.map, smap)
            scores = score_trajectories(
                trajs, require_success=not args.all_episodes, goal_tolerance=args.goal_tolerance
            )
    except (ValueError, KeyError, OSError) as err:
        message = err.args[0] if isinstance(err, KeyError) and err.args else str(err)
        print(f"socialnav metrics: error: {message}", file=sys.stderr)
        return EXIT_ERROR
    for w in caught:
        bucket = problems if issubclass(w.category, DataWarning) else notes
        if str(w.message) not in bucket:
            bucket.append(str(w.message))
    if args.json:
        out = {"files": args.file, "episodes": scores.rows, "summaries": scores.summaries,
               "notes": notes, "warnings": problems}
        print(json.dumps(json_safe(out)))
    else:
        _print_text(scores, args.per_episode, not args.all_episodes)
        for note in [] if args.quiet else notes:
            print(f"note: {note}", file=sys.stderr)
        for problem in problems:
            print(f"warning: {problem}", file=sys.stderr)
    return EXIT_WARNINGS if problems else 0


def _with_map(trajs: list[Any], path: str, smap: StaticMap) -> list[Any]:
    """The trajectories with ``smap``, read from ``path``; a note counts the stored maps it replaces."""
    import dataclasses
    import warnings

    replaced = sum(1 for t in trajs if t.static_map is not None and t.static_map != smap)
    if replaced:
        warnings.warn(f"--map {path} replaces the static map stored with {replaced} episode(s)",
                      UserWarning, stacklevel=2)
    return [dataclasses.replace(t, static_map=smap) for t in trajs]


def _print_text(scores: Any, per_episode: bool, require_success: bool) -> None:
    from socialnav.metrics.aggregate import metric_population

    rows = scores.rows
    ids = ("source", "scene", "episode", "ego", "mode", "outcome")
    # every row's keys: episodes without a static map lack the map_only metrics' (progress among walls)
    keys = [k for k in dict.fromkeys(k for row in rows for k in row) if k not in ids]
    several_files = len({row["source"] for row in rows}) > 1
    if per_episode or len(rows) <= _PER_EPISODE_LIMIT:
        for row in rows:
            who = f", ego {row['ego']}" if row["mode"] == "human_as_robot" else ""
            of = f" of {row['source']}" if several_files else ""
            print(f"episode {row['episode']}{of} ({row['outcome']}{who}):")
            for k in keys:
                if k in row:
                    print(f"  {k:60s} {row[k]:.4g}")
    words = {"all": "all episodes", "success": "successful episodes", "known_outcome": "known outcomes"}
    for group in scores.summaries:
        title = "dataset" if group["scope"] == "dataset" else f"scene {group['scenario']}"
        print(f"summary, {title} [{group['policy']}], {group['episodes']} episode(s):")
        for rate in ("success_rate", "collision_rate", "wall_collision_rate", "timeout_rate"):
            value = group.get(rate)
            if value is not None and math.isfinite(value):
                print(f"  {rate:60s} {value:.4g} (of known outcomes)")
        for k in keys:
            mean, std = group.get(f"{k}.mean"), group.get(f"{k}.std")
            if mean is None:
                continue
            population = words.get(metric_population(k, require_success), "")
            print(f"  {k:60s} {mean:.4g} ± {std:.3g} (n={group.get(f'{k}.n')} of {population})")
