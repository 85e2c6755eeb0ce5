"""Refusing episodes whose starts or goals lie in the obstacles of a map the scenario does not know.

A walled scenario places its agents clear of its own walls (``EpisodeBatch.validate`` checks it). A
World given a map of its own (its ``static_map`` argument, or ``set_static_map``) runs the scenario's
episodes among walls the scenario never saw: an agent could start inside one, or walk for ever towards
a goal inside one. The World checks every episode it loads into a slot with such a map, in the core
for the built-in scenarios (failure codes < 0) and here for the others, and raises :class:`MapError`
naming the episode, the agent, the point and the polygon.
"""

from __future__ import annotations

import numpy as np

from socialnav.maps.static_map import MapError, StaticMap


def first_covered(
    smap: StaticMap, start: np.ndarray, goal: np.ndarray, radius: np.ndarray, mask: np.ndarray
) -> tuple[int, int, str] | None:
    """The first (episode row, agent, "start" | "goal") whose disc touches an obstacle of ``smap``.

    Args:
        smap: The map.
        start: (E, A, 2) start positions [m].
        goal: (E, A, 2) goals [m].
        radius: (E, A) radii [m].
        mask: (E, A) real agents.

    Returns:
        None when every real agent's start and goal clear the map (distance >= radius), as the core's
        test (``disc_touches_obstacles``) decides it.
    """
    if not smap:
        return None
    start_hit = (smap.distance(start) < radius) & mask
    goal_hit = (smap.distance(goal) < radius) & mask
    hit = start_hit | goal_hit
    if not hit.any():
        return None
    # the core's order: episode by episode, agent by agent, the start before the goal
    row, agent = (int(v) for v in np.argwhere(hit)[0])
    return row, agent, "start" if start_hit[row, agent] else "goal"


def covered_message(
    scenario: str, smap: StaticMap, slot: int, episode: int, seed: int, agent: int, what: str,
    point: np.ndarray, radius: float,
) -> str:
    """The error for an agent whose start or goal the slot's map covers.

    Args:
        scenario: The scenario's name.
        smap: The slot's map.
        slot: The World slot.
        episode: The episode's index in its split.
        seed: The episode's seed.
        agent: 0 for the robot, j + 1 for human j.
        what: "start" or "goal".
        point: The covered point [m].
        radius: The agent's radius [m].

    Returns:
        A message naming the episode, the agent, the point, the nearest polygon and the way out.
    """
    distances = [float(StaticMap((poly,)).distance(point)) for poly in smap.polygons]
    polygon = int(np.argmin(distances))
    kind = "wall segment" if len(smap.polygons[polygon]) == 2 else "polygon"
    who = "the robot" if agent == 0 else f"human {agent - 1}"
    first = np.round(smap.polygons[polygon][0], 4).tolist()
    return (
        f"scenario {scenario}, episode {episode} (seed {seed}, slot {slot}): the {what} of {who} "
        f"{np.round(point, 4).tolist()} is covered by obstacle {polygon} of the world's static map (a {kind} "
        f"starting at {first}): distance {distances[polygon]:.3g} m < radius {radius:.3g} m. "
        f"The scenario places its agents without knowing this map: give the World a map "
        f"clear of the scenario's starts and goals, or use a scenario with walls of its own"
    )


def raise_first_covered(
    scenario: str, smap: StaticMap, slots: np.ndarray, episodes: np.ndarray, seeds: np.ndarray,
    start: np.ndarray, goal: np.ndarray, radius: np.ndarray, mask: np.ndarray,
) -> None:
    """Raises :class:`MapError` for the first of the episodes whose start or goal ``smap`` covers.

    Args:
        scenario: The scenario's name.
        smap: The slots' map.
        slots: (E,) the slots the episodes were loaded into.
        episodes: (E,) their indices in the split.
        seeds: (E,) their seeds.
        start: (E, A, 2) start positions [m] (agent 0 the robot).
        goal: (E, A, 2) goals [m].
        radius: (E, A) radii [m].
        mask: (E, A) real agents.
    """
    found = first_covered(smap, start, goal, radius, mask)
    if found is None:
        return
    row, agent, what = found
    point = (start if what == "start" else goal)[row, agent]
    raise MapError(covered_message(
        scenario, smap, int(slots[row]), int(episodes[row]), int(seeds[row]), agent, what, point,
        float(radius[row, agent]),
    ))
