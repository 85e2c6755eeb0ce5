"""Proves that two builds of the native core give bit-identical worlds, walled and open.

Runs a fixed set of seeded worlds (maps: the benchmark's spokes and room walls, solid polygons with a
non-convex block, and the open floor; ORCA and social-force humans; ORCA, social-force and linear
robots; 1 and 2 worker threads) for a few hundred steps with auto-reset, and hashes the state arrays
after every step into one SHA-256 per case; and, directly, every agent's obstacle half-planes
(``orca_obstacle_lines``) and the collision test of a swept disc for random states among random maps
of walls, squares and non-convex blocks (contacts included). With ``--against DIR`` it also runs itself with
``PYTHONPATH=DIR`` (a source tree holding the other build's ``_core``) and compares case by case.

    PYTHONPATH=src python tools/compare_core_digests.py --against build/base_src
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "benchmarks"))
from bench_world import room_walls, spoke_walls  # noqa: E402  (benchmarks/ is not a package)


def polygons() -> StaticMap:
    """A square pillar, a non-convex L-shaped block and two walls near the crossing's centre."""
    return StaticMap(tuple(0.75 * np.array(p) for p in (
        [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]],
        [[1.0, 1.0], [2.5, 1.0], [2.5, 1.5], [1.5, 1.5], [1.5, 2.5], [1.0, 2.5]],
        [[-2.5, 1.0], [-1.0, 2.0]],
        [[-2.0, -2.5], [-0.5, -1.5]],
    )))


MAPS = {
    "spokes": lambda: StaticMap(tuple(np.array(w) for w in spoke_walls())),
    "room": lambda: StaticMap(tuple(np.array(w) for w in room_walls())),
    "polygons": polygons,
    "open": lambda: None,
}
# (map, human model, robot policy, kinematics)
CASES = [
    ("spokes", "orca", "orca", "holonomic"),
    ("room", "orca", "orca", "holonomic"),
    ("polygons", "orca", "orca", "holonomic"),
    ("polygons", "orca", "orca", "unicycle"),
    ("spokes", "orca", "social_force", "holonomic"),
    ("polygons", "social_force", "linear", "holonomic"),
    ("open", "orca", "orca", "holonomic"),
    ("open", "orca", "orca", "unicycle"),
]


def case_digest(map_name: str, human_model: str, robot: str, kinematics: str, threads: int,
                batch: int, steps: int) -> str:
    """SHA-256 of the state after every step of one seeded run.

    Args:
        map_name: Key of ``MAPS``.
        human_model: ``WorldSettings.human_model``.
        robot: Robot policy name for ``make_policy``.
        kinematics: ``WorldSettings.kinematics``.
        threads: Native worker threads.
        batch: Episodes run at once.
        steps: Steps run (finished episodes are refilled).

    Returns:
        The hex digest.
    """
    settings = WorldSettings(time_limit=25.0, threads=threads, human_model=human_model, kinematics=kinematics)
    world = World(settings, make_scenario("circle_crossing", n_humans=5), batch, split="train", record=False,
                  static_map=MAPS[map_name]())
    policy = make_policy(robot, threads=threads) if robot != "linear" else make_policy(robot)
    obs = world.reset()
    h = hashlib.sha256()
    for _ in range(steps):
        obs = world.step(policy.act(obs), observe=True).observation
        for arr in (world.position, world.velocity, world.theta, world.steps, world.status, world.reward,
                    world.dmin):
            h.update(np.ascontiguousarray(arr).tobytes())
    world.close()
    return h.hexdigest()


def random_map(rng: np.random.Generator) -> StaticMap:
    """1-6 walls, squares and L-shaped (non-convex) blocks within 3 m of the origin."""
    parts = []
    for _ in range(int(rng.integers(1, 7))):
        kind, corner = int(rng.integers(3)), rng.uniform(-3.0, 3.0, 2)
        if kind == 0:
            parts.append(np.array([corner, corner + rng.uniform(-2.0, 2.0, 2) + 0.05]))
        else:
            shape = ([[0, 0], [1, 0], [1, 1], [0, 1]] if kind == 1
                     else [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]])
            parts.append(corner + rng.uniform(0.2, 1.0) * np.array(shape, dtype=float))
    return StaticMap(tuple(parts))


def geometry_digest(n_maps: int = 300, agents_per_map: int = 40) -> str:
    """SHA-256 of the obstacle half-planes and swept-disc collision tests of random agents.

    Args:
        n_maps: Random maps drawn.
        agents_per_map: Random agents per map (position within 4 m of the origin, so some touch or
            stand inside an obstacle; velocity up to 1.5 m/s; radius 0.1-0.5 m).

    Returns:
        The hex digest.
    """
    from socialnav import _core

    rng = np.random.default_rng(28)
    h = hashlib.sha256()
    for _ in range(n_maps):
        vertices, offsets = random_map(rng).to_flat()
        for _ in range(agents_per_map):
            p, v = rng.uniform(-4.0, 4.0, 2), rng.uniform(-1.5, 1.5, 2)
            radius, speed = float(rng.uniform(0.1, 0.5)), float(rng.uniform(0.5, 1.5))
            lines = _core.orca_obstacle_lines(p, v, radius, speed, vertices, offsets, 5.0)
            h.update(np.array(lines, dtype=float).tobytes())
            end = p + 0.25 * v
            hit = _core.swept_obstacle_clearance(p, end, radius, vertices, offsets) < 0.0
            # The world's own test, where the build has it.
            if hasattr(_core, "swept_disc_hits_obstacles"):
                if _core.swept_disc_hits_obstacles(p, end, radius, vertices, offsets) != hit:
                    raise AssertionError(f"collision tests differ at {p} -> {end}, radius {radius}")
            h.update(bytes([hit]))
    return h.hexdigest()


def all_digests(batch: int, steps: int) -> dict[str, str]:
    """Digests of every world case at 1 and 2 threads, and of the obstacle geometry.

    Keys: ``map/humans/robot/kinematics/threads`` and ``geometry``.
    """
    out = {f"{m}/{hm}/{r}/{k}/{t}": case_digest(m, hm, r, k, t, batch, steps)
           for m, hm, r, k in CASES for t in (1, 2)}
    out["geometry"] = geometry_digest()
    return out


def main() -> None:
    """Prints this build's digests, or the comparison with another build's, as JSON."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--batch", type=int, default=128)
    parser.add_argument("--steps", type=int, default=400)
    parser.add_argument("--against", help="source tree (PYTHONPATH) holding the other build's _core")
    args = parser.parse_args()
    np.seterr(all="ignore")
    ours = all_digests(args.batch, args.steps)
    if not args.against:
        print(json.dumps(ours, indent=1))
        return
    env = dict(os.environ, PYTHONPATH=os.path.abspath(args.against))
    other = json.loads(subprocess.run(
        [sys.executable, os.path.abspath(__file__), "--batch", str(args.batch), "--steps", str(args.steps)],
        env=env, check=True, capture_output=True, text=True).stdout)
    same = {case: ours[case] == other[case] for case in ours}
    for case, equal in same.items():
        print(f"{case}: {'identical' if equal else 'DIFFERENT'}")
    print(json.dumps({"cases": len(same), "identical": sum(same.values()),
                      "all_identical": all(same.values()), "batch": args.batch, "steps": args.steps}))
    sys.exit(0 if all(same.values()) else 1)


if __name__ == "__main__":
    main()
