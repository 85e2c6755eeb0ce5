"""Gymnasium ids: ``socialnav/CircleCrossing-v0`` and friends (single and vector entry points).

Gymnasium 1.x has no plugin entry points, so the ids are registered when :mod:`socialnav` is
imported (``import socialnav``), and ``gym.make("socialnav:socialnav/CircleCrossing-v0")`` works
without any import (Gymnasium imports the module before the ``:``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym

from socialnav.envs.render import RENDER_MODES

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


def make_env(**kwargs: Any) -> gym.Env:
    """``gym.make``'s entry point: a :class:`~socialnav.envs.single.SocialNavEnv`.

    Its ``metadata`` lists every render mode, so that ``gym.make(..., render_mode="human")`` reaches
    the env, which explains what is missing (a display, matplotlib), instead of Gymnasium wrapping an
    ``rgb_array`` env in its pygame window (and failing with "pygame is not installed"). The env's
    own ``metadata`` lists ``human`` only where a display exists, so the env checker tries no window.
    """
    from socialnav.envs.single import SocialNavEnv

    return SocialNavEnv(**kwargs)


make_env.metadata = {"render_modes": list(RENDER_MODES), "render_fps": 4}  # type: ignore[attr-defined]


def register_envs() -> None:
    """Registers the ids (idempotent)."""
    for env_id, kwargs in ENV_IDS.items():
        if env_id in gym.registry:
            continue
        gym.register(
            id=env_id,
            entry_point="socialnav.envs.registration:make_env",
            vector_entry_point="socialnav.envs.vector:SocialNavVectorEnv",
            kwargs=kwargs,
        )


register_envs()
