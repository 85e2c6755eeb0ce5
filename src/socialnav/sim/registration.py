"""Gymnasium ids: ``socialnav/CircleCrossing-v0`` and friends (single and vector entry points)."""

from __future__ import annotations

import gymnasium as gym

ENV_IDS = {
    "socialnav/CircleCrossing-v0": {"scenario": "circle_crossing"},
    "socialnav/SquareCrossing-v0": {"scenario": "square_crossing"},
    "socialnav/ParallelTraffic-v0": {"scenario": "parallel_traffic"},
    "socialnav/PerpendicularTraffic-v0": {"scenario": "perpendicular_traffic"},
    "socialnav/Random-v0": {"scenario": "random"},
}


def register_envs() -> None:
    """Registers the ids (idempotent); called by Gymnasium's plugin loader and on import."""
    for env_id, kwargs in ENV_IDS.items():
        if env_id in gym.registry:
            continue
        gym.register(id=env_id, entry_point="socialnav.sim.env:SocialNavEnv",
                     vector_entry_point="socialnav.sim.env:SocialNavVectorEnv", kwargs=kwargs)


register_envs()
