"""navground comparison workload: circle crossing with 6 ORCA agents.

``navground_env_steps_per_s`` measures navground's own simulator
(``navground.sim.World``, C++ loop driven by ``World.run(steps, dt)``) on:

* 6 agents, radius 0.3 m, holonomic (``OmnidirectionalKinematics``),
  max speed = optimal speed = 1 m/s;
* ``ORCABehavior`` (RVO2) with time horizon 5 s, neighbour range
  ``2 * horizon = 10 m`` (covers the whole 8 m circle), safety margin 0;
* perfect sensing of neighbours within 10 m (``BoundedStateEstimation``);
* agents start on a circle of radius 4 m (seeded angular jitter of up to
  +-0.2 rad to break the perfect symmetry) and go to the antipode; a looping
  ``WaypointsTask([antipode, start])`` re-targets them on arrival so all six
  stay active for the whole measurement;
* plain ORCA (navground does not perturb preferred velocities like the RVO2
  demo does) often jams symmetric circle crossings in the centre; a jammed
  world (all agents slower than 0.05 m/s after a chunk of steps) is replaced
  by a fresh one with a new seed, outside the timed region;
* time step 0.25 s, control every step (``control_period = 0``); navground's
  default collision bookkeeping stays on.

One env-step = one ``World`` step of all 6 agents (sensing, ORCA, actuation,
collision check).  ``navground`` is imported lazily.

With ``walls`` (a list of ``((x1, y1), (x2, y2))`` segments), the worlds also hold
those walls (``navground.sim.Wall``); the agents' state estimation hands the ones in
range to RVO2 as 2-vertex obstacles, with ``static_time_horizon`` 5 s (CrowdSim's
``timeHorizonObst``).

With ``lidar`` beams, agent 0 also carries navground's ``LidarStateEstimation`` (that many
beams over the full circle, ``lidar_range`` metres), updated every step with the others.
"""

from __future__ import annotations

import math
import time

N_AGENTS = 6
RADIUS = 0.3
SPEED = 1.0
TIME_HORIZON = 5.0
TIME_STEP = 0.25
CIRCLE_RADIUS = 4.0
NEIGHBOR_RANGE = 10.0
GOAL_TOLERANCE = 0.25
JITTER = 0.2  # rad
CHUNK = 100  # world steps per World.run call
JAM_SPEED = 0.05  # m/s


def _import_navground():
    try:
        from navground import core, sim
        from navground.core.behaviors import ORCABehavior
        from navground.core.kinematics import OmnidirectionalKinematics
        from navground.sim.state_estimations import BoundedStateEstimation
        from navground.sim.tasks import WaypointsTask
    except ImportError as exc:
        raise ImportError(
            "benchmarks/_navground_workload.py needs navground "
            "(pip install navground==0.7.0); it is only used for the comparison "
            "benchmark and is not a dependency of socialnav") from exc
    return core, sim, ORCABehavior, OmnidirectionalKinematics, BoundedStateEstimation, WaypointsTask


def make_circle_world(seed: int = 0, walls=(), lidar: int = 0, lidar_range: float = 10.0):
    """A navground ``World`` with 6 ORCA agents crossing a 4 m circle (and ``walls``, and a lidar on
    agent 0 with ``lidar`` beams)."""
    import numpy as np

    (_core, sim, ORCABehavior, OmnidirectionalKinematics, BoundedStateEstimation,
     WaypointsTask) = _import_navground()
    rng = np.random.default_rng(seed)
    world = sim.World()
    world.seed = int(seed)
    for i in range(N_AGENTS):
        angle = 2.0 * math.pi * i / N_AGENTS + rng.uniform(-JITTER, JITTER)
        start = np.array([math.cos(angle), math.sin(angle)]) * CIRCLE_RADIUS
        goal = -start
        kinematics = OmnidirectionalKinematics(max_speed=SPEED)
        behavior = ORCABehavior(kinematics=kinematics, radius=RADIUS)
        behavior.optimal_speed = SPEED
        behavior.time_horizon = TIME_HORIZON
        behavior.static_time_horizon = TIME_HORIZON
        behavior.horizon = 0.5 * NEIGHBOR_RANGE  # ORCA neighbour range = 2 * horizon
        behavior.safety_margin = 0.0
        agent = sim.Agent(
            radius=RADIUS, behavior=behavior, kinematics=kinematics,
            task=WaypointsTask(waypoints=[goal, start], loop=True, tolerance=GOAL_TOLERANCE),
            state_estimations=[BoundedStateEstimation(range=NEIGHBOR_RANGE)],
            control_period=0.0, id=i)
        if lidar and i == 0:
            from navground.sim.state_estimations import LidarStateEstimation

            agent.state_estimations = [*agent.state_estimations, LidarStateEstimation(
                range=lidar_range, start_angle=-math.pi, field_of_view=2 * math.pi, resolution=lidar)]
        agent.position = start
        agent.orientation = angle + math.pi
        world.add_agent(agent)
    for p1, p2 in walls:
        world.add_wall(sim.Wall(np.asarray(p1, dtype=float), np.asarray(p2, dtype=float)))
    return world


def _jammed(world) -> bool:
    return max(math.hypot(*a.velocity) for a in world.agents) < JAM_SPEED


def navground_env_steps_per_s(n_worlds: int = 1, seconds: float = 3.0, seed: int = 0, walls=(),
                              lidar: int = 0, lidar_range: float = 10.0) -> dict:
    """Env-steps/s of navground stepping ``n_worlds`` 6-agent ORCA worlds.

    Worlds are stepped one after the other (single thread) with
    ``World.run(CHUNK, 0.25)``, the C++ stepping loop (one Python call per
    100 steps, ~1 ms).  Only the time inside ``World.run`` is counted (at
    least ``seconds`` of it, ``time.perf_counter``); jam checks/resets happen
    between chunks, untimed.  Returns ``{"env_steps_per_s",
    "agent_steps_per_s", "agents"}`` (+ ``n_worlds``, ``jam_resets``), where
    env-steps are single-world steps summed over all worlds.
    """
    if n_worlds < 1:
        raise ValueError("n_worlds must be >= 1")
    next_seed = seed
    worlds = []
    for _ in range(n_worlds):
        worlds.append(make_circle_world(next_seed, walls, lidar, lidar_range))
        next_seed += 1
    # warm-up (first steps initialise navground's internal state/caches)
    for w in worlds:
        w.run(2 * CHUNK, TIME_STEP)

    steps = 0
    resets = 0
    elapsed = 0.0
    while elapsed < seconds:
        for k, w in enumerate(worlds):
            t0 = time.perf_counter()
            w.run(CHUNK, TIME_STEP)
            elapsed += time.perf_counter() - t0
            steps += CHUNK
            if _jammed(w):
                worlds[k] = make_circle_world(next_seed, walls, lidar, lidar_range)
                next_seed += 1
                resets += 1
    idle = sum(1 for w in worlds for a in w.agents if a.idle)
    if idle:  # pragma: no cover - sanity check
        raise RuntimeError(f"{idle} navground agents became idle")
    env_steps_per_s = steps / elapsed
    return {"env_steps_per_s": env_steps_per_s,
            "agent_steps_per_s": env_steps_per_s * N_AGENTS,
            "agents": N_AGENTS,
            "n_worlds": n_worlds,
            "jam_resets": resets}


if __name__ == "__main__":  # pragma: no cover
    print(navground_env_steps_per_s())
