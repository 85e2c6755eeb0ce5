"""Helpers for worlds with static obstacles (tests only)."""

from __future__ import annotations

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import World


def with_map(scenario, static_map: StaticMap | None):
    """``scenario`` with one static map for all its episodes (the ``static_map`` attribute the World
    reads; the built-in scenarios have none, so the test sets it on the frozen instance)."""
    object.__setattr__(scenario, "static_map", static_map)
    return scenario


def walled_world(static_map: StaticMap | None, n_humans: int = 5, batch: int = 2, count: int | None = None,
                 scenario: str = "circle_crossing", **settings) -> World:
    settings.setdefault("threads", 1)
    return World(WorldSettings(**settings), make_scenario(scenario, n_humans=n_humans), batch, split="test",
                 count=batch if count is None else count, static_map=static_map)


def pillars_and_walls() -> StaticMap:
    """Obstacles within 2.4 m of the centre of circle_crossing's 4 m circle (humans start and end
    beyond ~3.3 m, start noise included): a square pillar, a non-convex L-shaped block and two wall
    segments."""
    return StaticMap(tuple(0.75 * np.array(p) for p in (
        [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]],
        [[1.0, 1.0], [2.5, 1.0], [2.5, 1.5], [1.5, 1.5], [1.5, 2.5], [1.0, 2.5]],
        [[-2.5, 1.0], [-1.0, 2.0]],
        [[-2.0, -2.5], [-0.5, -1.5]],
    )))


def human_clearances(world: World) -> np.ndarray:
    """(B, N) distance from every real human's centre to its slot's obstacles minus its radius."""
    out = np.full((world.batch_size, world.n_agents - 1), np.inf)
    for b, static_map in enumerate(world.static_maps):
        if static_map is None:
            continue
        real = world.mask[b, 1:].astype(bool)
        out[b, real] = static_map.distance(world.position[b, 1:][real]) - world.radius[b, 1:][real]
    return out
