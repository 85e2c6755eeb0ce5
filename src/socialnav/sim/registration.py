"""Gymnasium ids: ``socialnav/CircleCrossing-v0`` and friends (single and vector entry points).

Gymnasium 1.x has no plugin entry points, so the ids are registered when :mod:`socialnav` is
imported (``import socialnav``), and ``gym.make("socialnav:socialnav/CircleCrossing-v0")`` works
without any import (Gymnasium imports the module before the ``:``).
"""

from __future__ import annotations

import gymnasium as gym

#: The protocol's scenarios (and CrowdNav's square crossing); ``Passing``, ``Overtaking`` and
#: ``Crossing`` are the single-human side-preference sweeps (finite: their episodes cycle).
ENV_IDS = {
    "socialnav/CircleCrossing-v0": {"scenario": "circle_crossing"},
    "socialnav/SquareCrossing-v0": {"scenario": "square_crossing"},
    "socialnav/ParallelTraffic-v0": {"scenario": "parallel_traffic"},
    "socialnav/PerpendicularTraffic-v0": {"scenario": "perpendicular_traffic"},
    "socialnav/Random-v0": {"scenario": "random"},
    "socialnav/Passing-v0": {"scenario": "passing"},
    "socialnav/Overtaking-v0": {"scenario": "overtaking"},
    "socialnav/Crossing-v0": {"scenario": "crossing"},
}


def register_envs() -> None:
    """Registers the ids (idempotent)."""
    for env_id, kwargs in ENV_IDS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point="socialnav.sim.env:SocialNavEnv",
            vector_entry_point="socialnav.sim.env:SocialNavVectorEnv",
            kwargs=kwargs,
        )


register_envs()
