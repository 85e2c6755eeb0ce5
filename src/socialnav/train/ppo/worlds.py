"""The PPO trainer's view of the worlds.

One lockstep step of the whole training mix, the saved state of the episodes in flight (resumption
mid-episode, bit-identical on CPU) and the goal distance of the reward term.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch

from socialnav.settings import ConfigError
from socialnav.sim.observation import Observation, ObstacleArrays
from socialnav.sim.world import EpisodeStream
from socialnav.train.worlds import MultiWorld, concat_optional, pad_humans

#: The World arrays that hold an episode's state (saved with last.pt so that a resumed run goes on
#: with the same episodes in flight).
WORLD_STATE = (
    "position",
    "velocity",
    "goal",
    "radius",
    "v_pref",
    "mask",
    "theta",
    "steps",
    "status",
    "reward",
    "dmin",
    "done",
    "overlaps",
    "arrival",
    "end_step",
    "episode_index",
    "episode_seed",
)


def world_snapshot(world: MultiWorld) -> list[dict[str, Any]]:
    """The state of every world's episodes in flight and its stream position (plain tensors).

    Worlds with ``human_routes`` also save where their humans stand on their routes (``routes``), worlds
    with ``sensing.latency`` the past states their delayed detections come from (``sensing``), a
    differential-drive robot the (v, ω) it last drove (``twist``).
    """
    out = []
    for w in world.worlds:
        saved: dict[str, Any] = {k: torch.from_numpy(np.array(getattr(w, k))) for k in WORLD_STATE}
        saved["next_index"] = int(w.stream.next_index)
        if w.settings.human_routes != "none":
            saved["routes"] = [torch.from_numpy(r) for r in w.route_state()]
        if w.settings.sensing.latency:
            saved["sensing"] = [torch.from_numpy(r) for r in w.sensing_state()]
        twist = w.robot_twist(new_at_rest=False)
        if twist is not None:
            saved["twist"] = torch.from_numpy(twist)
        out.append(saved)
    return out


def restore_worlds(world: MultiWorld, snapshot: list[dict[str, Any]]) -> None:
    """Puts the worlds back into a :func:`world_snapshot` state (their streams continue from it).

    The episodes in flight get their static maps back: a map is drawn from the episode's index and
    seed alone, so the scenario draws it again (the snapshot holds no maps; without this, a resumed
    run would go on with its episodes in flight on open floors). Routed humans get their routes back.
    """
    if len(snapshot) != len(world.worlds):
        raise ConfigError(f"the saved run has {len(snapshot)} worlds, this one {len(world.worlds)}")
    for w, saved in zip(world.worlds, snapshot, strict=True):
        w.stream = EpisodeStream(w.scenario, w.stream.split, int(saved["next_index"]))
        for k in WORLD_STATE:
            np.copyto(getattr(w, k), saved[k].numpy())
        live = np.flatnonzero(w.episode_index >= 0)
        maps = w.scenario.episode_maps(w.episode_seed[live], w.episode_index[live]) if live.size else None
        if maps is not None:
            for slot, static_map in zip(live, maps, strict=True):
                w.set_static_map(int(slot), static_map)
        if "routes" in saved:  # after the maps: the routes' graphs are those of the slots' maps
            w.set_route_state([r.numpy() for r in saved["routes"]])
        if "sensing" in saved:
            w.set_sensing_state([r.numpy() for r in saved["sensing"]])
        if "twist" in saved:
            w.set_robot_twist(saved["twist"].numpy())


def step_worlds(world: MultiWorld, actions: np.ndarray):
    """Steps every world of the mix once (one native call each).

    Worlds with fewer humans than the mix's largest crowd get padded slots (mask False).

    Args:
        world: the training worlds.
        actions: (B, 2) one action per slot.

    Returns:
        Reward, terminated, truncated, the final observation (every slot's state right after the
        step, before refills, with the map it was in) and the observation the policy sees next
        (refilled slots at time 0, with their new episode's map); ``obstacles`` is None on open floors.
    """
    n = world.n_human_slots
    parts, stepped_maps, next_maps = [], [], []
    for w, lo, hi in zip(world.worlds, world.offsets[:-1], world.offsets[1:], strict=True):
        stepped_maps.extend(w.static_maps)  # the maps the step happened in, before refills
        res = w.step(actions[lo:hi], final_observation=True, observe=True)
        next_maps.extend(w.static_maps)
        nxt = res.observation
        final = [nxt.robot.copy(), nxt.humans.copy(), nxt.human_mask.copy(), nxt.time.copy(),
                 None if nxt.lidar is None else nxt.lidar.copy(),
                 None if nxt.robot_twist is None else nxt.robot_twist.copy()]
        done = np.flatnonzero(res.terminated | res.truncated)
        if done.size:
            fo = res.final_observation
            final[0][done], final[1][done], final[2][done], final[3][done] = (
                fo.robot,
                fo.humans,
                fo.human_mask,
                fo.time,
            )
            if final[4] is not None:
                final[4][done] = fo.lidar
            if final[5] is not None:
                final[5][done] = fo.robot_twist
        final[1], final[2] = pad_humans(final[1], final[2], n)
        humans, mask = pad_humans(nxt.humans, nxt.human_mask, n)
        nxt = Observation(nxt.robot, humans, mask, nxt.active, nxt.time, nxt.dt, nxt.kinematics,
                          lidar=nxt.lidar, robot_twist=nxt.robot_twist)
        parts.append((res.reward, res.terminated, res.truncated, final, nxt))
    cat = np.concatenate
    reward, term, trunc = (cat([p[i] for p in parts]) for i in range(3))
    first = parts[0][4]
    final = Observation(
        *(cat([p[3][i] for p in parts]) for i in range(3)),
        np.ones(len(reward), dtype=bool),
        cat([p[3][3] for p in parts]),
        first.dt,
        first.kinematics,
        obstacles=ObstacleArrays.from_maps(stepped_maps),
        lidar=concat_optional([p[3][4] for p in parts]),
        robot_twist=concat_optional([p[3][5] for p in parts]),
    )
    nxt = Observation(
        cat([p[4].robot for p in parts]),
        cat([p[4].humans for p in parts]),
        cat([p[4].human_mask for p in parts]),
        cat([p[4].active for p in parts]),
        cat([p[4].time for p in parts]),
        first.dt,
        first.kinematics,
        obstacles=ObstacleArrays.from_maps(next_maps),
        lidar=concat_optional([p[4].lidar for p in parts]),
        robot_twist=concat_optional([p[4].robot_twist for p in parts]),
    )
    return reward, term, trunc, final, nxt


def goal_distance(robot: np.ndarray) -> np.ndarray:
    """(B,) distance from the robot to its goal [m] of (B, 9) observation rows."""
    return np.hypot(robot[:, 5] - robot[:, 0], robot[:, 6] - robot[:, 1])


def route_distance(obs: Observation) -> np.ndarray:
    """(B,) the length [m] of each robot's route to its goal around its walls (goal_distance on open floors).

    The point a route heads for stands as far from the robot as the route is long
    (:func:`socialnav.maps.routes.route_goals`).
    """
    from socialnav.policies.learned.ppo_inputs import with_route_goals

    return goal_distance(with_route_goals(obs).robot if obs.obstacles is not None else obs.robot)
