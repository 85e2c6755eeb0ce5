"""How building the route graphs grows with a map's size (docs/routes.md, "Cost").

A map's route graphs (docs/routes.md: its nodes by the walls' corners, and an edge between every two
nodes that see each other with the inflation's clearance) are built once per distinct map and inflation,
at the first plan on it, and cached. ``orca_route`` builds one for every call in which somebody stands
still (the walls and the standing people together), so on a large map their cost is paid per step.

The maps are office-like grids of short wall segments (1.5 m long, 3 m apart, alternating horizontal and
vertical), 25 to ``--max-walls`` segments. Each is timed from an empty cache: one plan across the map that
builds the graphs of both inflations of a 0.3 m agent with the default 0.2 m clearance (best of
``--repeats``). The reference is the 25-wall map in the same run: ``ratio_<n>_vs_25`` is how many times
its build takes, and ``growth_exponent`` the slope of log time over log walls between the two largest
maps (2: quadratic, 3: cubic).

    python benchmarks/bench_route_graphs.py [--max-walls 200] [--repeats 3] [--record]

Prints one line per map, then one JSON object last.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import add_record_arguments, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

from socialnav import _core  # noqa: E402
from socialnav.maps import StaticMap  # noqa: E402
from socialnav.maps.routes import plan_route  # noqa: E402


def grid_walls(n: int) -> StaticMap:
    """``n`` wall segments 1.5 m long on a 3 m grid, horizontal and vertical in turn (cubicle walls)."""
    k = math.ceil(math.sqrt(n))
    walls = []
    for i in range(k):
        for j in range(k):
            if len(walls) == n:
                break
            x, y = 3.0 * i, 3.0 * j
            walls.append([[x, y], [x + 1.5, y]] if (i + j) % 2 else [[x, y], [x, y + 1.5]])
    return StaticMap(tuple(np.array(w) for w in walls))


def build_ms(static_map: StaticMap, repeats: int) -> float:
    """Milliseconds of the first plan on the map (both graphs built), best of ``repeats``."""
    far = 3.0 * math.ceil(math.sqrt(len(static_map)))
    best = math.inf
    for _ in range(repeats):
        _core.clear_route_cache()
        start = time.perf_counter()
        plan_route(static_map, (-1.0, -1.0), (far + 1.0, far + 1.0), radius=0.3)
        best = min(best, time.perf_counter() - start)
    _core.clear_route_cache()
    return 1e3 * best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--max-walls", type=int, default=200, help="the largest map's wall segments (>= 50)")
    parser.add_argument("--repeats", type=int, default=3, help="builds per map, the best kept")
    add_record_arguments(parser, "bench_route_graphs")
    args = parser.parse_args()
    if args.max_walls < 50 or args.repeats < 1:
        parser.error("--max-walls must be >= 50 and --repeats >= 1")
    sizes = [25]
    while sizes[-1] * 2 <= args.max_walls:
        sizes.append(sizes[-1] * 2)
    times = {}
    for n in sizes:
        times[n] = build_ms(grid_walls(n), args.repeats)
        print(f"{n} walls: route graphs built in {times[n]:.2f} ms", flush=True)
    a, b = sizes[-2], sizes[-1]
    result = run_record() | {
        "walls": sizes,
        **{f"graph_ms_{n}_walls": round(times[n], 3) for n in sizes},
        **{f"ratio_{n}_vs_25": round(times[n] / times[25], 2) for n in sizes[1:]},
        "growth_exponent": round(math.log(times[b] / times[a]) / math.log(b / a), 2),
        "repeats": args.repeats,
    }
    emit(result, args)


if __name__ == "__main__":
    main()
