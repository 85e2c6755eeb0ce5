"""RVO2 itself, with polygon obstacles and its obstacle kd-tree, through ``pyrvo`` (PyPI, RVO2 2.0).

``pyrvo`` wraps the RVO2 library: ``addObstacle`` of any polygon (2 vertices: a two-sided segment),
``processObstacles`` (the kd-tree, which splits every edge that crosses the line of the edge chosen
at a node), one ``doStep``. Its build is float32; its output equals Python-RVO2's bit for bit.

The layouts drawn here are what socialnav's maps hold: crossing and free wall segments, convex
polygons, star-shaped non-convex polygons, doorways of two walls, and boxes, with 3 to 9 agents
outside them. ``float32_sensitive`` tells the cases whose answer depends on float32 rounding, where
RVO2's float and double builds disagree (tests/sim/test_orca_rvo2_reference.py).
"""

from __future__ import annotations

import importlib.util

import numpy as np

from socialnav import _core
from socialnav.maps import StaticMap
from socialnav.sim import orca_step
from tests.reference.navground_orca_walls import solve_with_hard_lines
from tests.reference.python_orca import orca_lines

#: RVO2's parameters of the cases (its ``addAgent`` arguments and time step).
PARAMS = {
    "time_step": 0.25,
    "neighbor_dist": 10.0,
    "max_neighbors": 10,
    "time_horizon": 5.0,
    "time_horizon_obst": 5.0,
}
KINDS = ("segments", "convex", "nonconvex", "doorway", "boxes")
FLOAT32_ULP = 2.0**-23


def pyrvo_available() -> bool:
    """Whether ``pyrvo`` (the test extra) is installed."""
    return importlib.util.find_spec("pyrvo") is not None


def rvo2_step(case: dict) -> tuple[np.ndarray, list[list[int]]]:
    """RVO2's new velocities (n, 2) of a case's agents and each agent's obstacle neighbours (RVO2's
    obstacle ids, nearest first)."""
    import pyrvo

    sim = pyrvo.RVOSimulator()
    sim.set_time_step(PARAMS["time_step"])
    for polygon in case["obstacles"]:
        sim.add_obstacle([tuple(map(float, v)) for v in polygon])
    sim.process_obstacles()
    for i, position in enumerate(case["positions"]):
        agent = sim.add_agent(
            tuple(map(float, position)),
            PARAMS["neighbor_dist"],
            PARAMS["max_neighbors"],
            PARAMS["time_horizon"],
            PARAMS["time_horizon_obst"],
            float(case["radii"][i]),
            float(case["max_speeds"][i]),
            tuple(map(float, case["velocities"][i])),
        )
        sim.set_agent_pref_velocity(agent, tuple(map(float, case["pref_velocities"][i])))
    sim.do_step()
    n = len(case["positions"])
    velocities = np.array([[sim.get_agent_velocity(i).x, sim.get_agent_velocity(i).y] for i in range(n)])
    neighbors = [
        [sim.get_agent_obstacle_neighbor(i, k) for k in range(sim.get_agent_num_obstacle_neighbors(i))]
        for i in range(n)
    ]
    return velocities, neighbors


def core_step(case: dict) -> np.ndarray:
    """socialnav's new velocities (n, 2) of the same case (``socialnav.sim.orca_step``)."""
    return orca_step(
        np.asarray(case["positions"], float),
        np.asarray(case["velocities"], float),
        np.asarray(case["pref_velocities"], float),
        np.asarray(case["radii"], float),
        np.asarray(case["max_speeds"], float),
        StaticMap.from_polygons([np.asarray(p, float) for p in case["obstacles"]]),
        time_step=PARAMS["time_step"],
        time_horizon=PARAMS["time_horizon"],
        time_horizon_obst=PARAMS["time_horizon_obst"],
        neighbor_dist=PARAMS["neighbor_dist"],
        max_neighbors=PARAMS["max_neighbors"],
    )


def _flat(case: dict) -> tuple[np.ndarray, np.ndarray]:
    return StaticMap.from_polygons([np.asarray(p, float) for p in case["obstacles"]]).to_flat()


def core_obstacle_neighbors(case: dict, i: int) -> tuple[list[int], dict[int, float]]:
    """socialnav's obstacle neighbours of agent i (ids as RVO2 numbers its vertices and split points),
    and the squared distance from the agent to the edge of every vertex of the split map."""
    vertices, offsets = _flat(case)
    c = np.asarray(case["positions"][i], float)
    neighbors, split = _core.orca_obstacle_neighbors(
        c,
        float(case["radii"][i]),
        float(case["max_speeds"][i]),
        vertices,
        offsets,
        PARAMS["time_horizon_obst"],
    )
    distances = {}
    for k, (x, y, nxt, *_rest) in enumerate(split):
        a, b = np.array([x, y]), np.array(split[nxt][:2])
        r = np.clip(np.dot(c - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
        distances[k] = float(np.sum((c - (a + r * (b - a))) ** 2))
    return list(neighbors), distances


def float32_sensitive(case: dict, i: int, tolerance: float = 5e-6) -> str | None:
    """Why agent i's answer depends on float32 rounding (None when no check shows it):

    - ``"inputs"``: the core's answer moves by more than ``tolerance`` when every input moves by
      about one float32 ulp (what RVO2's float build rounds them to);
    - ``"half-planes"``: RVO2's programs solved in float64 on the core's half-planes and on the same
      half-planes rounded to float32 give answers ``tolerance`` apart (a feasible set that is almost
      a point, where rounding decides what the 3-D fallback keeps).
    """
    base = core_step(case)[i]
    rng = np.random.default_rng(i)

    def jitter(x):
        x = np.asarray(x, float)
        return x * (1.0 + rng.choice([-1.0, 1.0], x.shape) * FLOAT32_ULP)

    for _ in range(4):
        moved = {
            k: jitter(case[k]) for k in ("positions", "velocities", "pref_velocities", "radii", "max_speeds")
        }
        moved["obstacles"] = [jitter(p) for p in case["obstacles"]]
        try:
            if np.abs(core_step(moved)[i] - base).max() > tolerance:
                return "inputs"
        except ValueError:  # the jitter made a polygon degenerate: as sensitive as it gets
            return "inputs"
    vertices, offsets = _flat(case)
    p = np.asarray(case["positions"], float)
    v = np.asarray(case["velocities"], float)
    r = np.asarray(case["radii"], float)
    speed = float(case["max_speeds"][i])
    obstacle = [
        ((a, b), (c, d))
        for a, b, c, d in _core.orca_obstacle_lines(
            p[i], v[i], r[i], speed, vertices, offsets, PARAMS["time_horizon_obst"]
        )
    ]
    others = [j for j in range(len(p)) if j != i]
    agents = orca_lines(
        p[i],
        v[i],
        r[i],
        p[others],
        v[others],
        r[others],
        PARAMS["time_horizon"],
        PARAMS["time_step"],
        PARAMS["neighbor_dist"],
        PARAMS["max_neighbors"],
    )
    lines = obstacle + list(agents)
    rounded = [
        (tuple(np.float32(x) for x in point), tuple(np.float32(x) for x in direction))
        for point, direction in lines
    ]
    pref = case["pref_velocities"][i]
    exact = solve_with_hard_lines(lines, len(obstacle), speed, pref)
    as_float = solve_with_hard_lines(rounded, len(obstacle), float(np.float32(speed)), pref)
    if np.abs(exact - as_float).max() > tolerance:
        return "half-planes"
    return None


def _ccw(polygon: list) -> list:
    area = sum(
        polygon[k][0] * polygon[(k + 1) % len(polygon)][1]
        - polygon[(k + 1) % len(polygon)][0] * polygon[k][1]
        for k in range(len(polygon))
    )
    return polygon if area > 0 else polygon[::-1]


def _around(rng: np.random.Generator, centre, radii, k: int) -> list:
    angles = np.sort(rng.uniform(0.0, 2.0 * np.pi, k))
    return _ccw(
        [[centre[0] + r * np.cos(a), centre[1] + r * np.sin(a)] for a, r in zip(angles, radii, strict=True)]
    )


def _obstacles(rng: np.random.Generator, kind: str) -> list:
    if kind == "segments":
        return [rng.uniform(-3, 3, (2, 2)).tolist() for _ in range(rng.integers(2, 6))]
    if kind == "convex":
        return [
            _around(rng, rng.uniform(-3, 3, 2), [rng.uniform(0.3, 1.2)] * (k := int(rng.integers(3, 7))), k)
            for _ in range(rng.integers(1, 4))
        ]
    if kind == "nonconvex":
        return [
            _around(rng, rng.uniform(-2.5, 2.5, 2), rng.uniform(0.3, 1.8, k := int(rng.integers(4, 9))), k)
            for _ in range(rng.integers(1, 3))
        ]
    if kind == "doorway":
        gap, width, t = rng.uniform(-1, 1), rng.uniform(0.8, 1.6), 0.1
        walls = [
            [[-4, -t], [gap - width / 2, -t], [gap - width / 2, t], [-4, t]],
            [[gap + width / 2, -t], [4, -t], [4, t], [gap + width / 2, t]],
        ]
        return walls + ([rng.uniform(-3, 3, (2, 2)).tolist()] if rng.random() < 0.5 else [])
    boxes = []
    for _ in range(rng.integers(1, 5)):
        (x, y), (w, h) = rng.uniform(-3, 3, 2), rng.uniform(0.2, 1.0, 2)
        boxes.append([[x - w, y - h], [x + w, y - h], [x + w, y + h], [x - w, y + h]])
    return boxes


def random_case(rng: np.random.Generator, kind: str) -> dict:
    """One layout of ``kind`` (a valid StaticMap) with 3 to 9 agents clear of it and of each other."""
    while True:
        obstacles = _obstacles(rng, kind)
        try:
            walls = StaticMap.from_polygons([np.asarray(p, float) for p in obstacles])
            break
        except ValueError:  # a self-intersecting star: draw again
            continue
    positions, radii = [], []
    wanted = int(rng.integers(3, 10))
    for _ in range(2000):
        if len(positions) == wanted:
            break
        p = rng.uniform(-4, 4, 2)
        r = 0.31 if rng.random() < 0.7 else float(rng.uniform(0.3, 0.5))
        if walls.distance(p[None])[0] <= r or walls.contains(p[None])[0]:
            continue
        if any(np.hypot(*(p - q)) <= r + s for q, s in zip(positions, radii, strict=True)):
            continue
        positions.append(p)
        radii.append(r)
    n = len(positions)
    pref = rng.normal(size=(n, 2))
    pref /= np.linalg.norm(pref, axis=1, keepdims=True)
    return {
        "kind": kind,
        "obstacles": obstacles,
        "positions": np.array(positions),
        "velocities": rng.uniform(-1, 1, (n, 2)),
        "pref_velocities": pref,
        "radii": np.array(radii),
        "max_speeds": np.where(rng.random(n) < 0.7, 1.0, rng.uniform(0.6, 1.4, n)),
    }
