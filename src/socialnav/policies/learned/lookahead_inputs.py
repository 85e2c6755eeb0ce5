"""An observation as the value policy's lookahead reads it: obstacle points appended, then tensors.

:class:`~socialnav.policies.learned.value_policy.ValuePolicy` accepts an
:class:`~socialnav.sim.observation.Observation`, any object with its attributes, or a mapping with its
keys (a Gymnasium dict observation), as NumPy arrays or torch tensors. This module turns each into one
form: the robot (B, 9), human (B, N, 5) and mask (B, N) tensors on the policy's device, the step
``dt``, and the number of trailing slots that are obstacle points (``static_slots``).

Obstacles (:mod:`socialnav.sim.obstacle_points`): with an obstacle encoding, the nearest points of the
episode's obstacle outlines are appended after the human slots as standing agents, so the networks read
them like humans. An open floor gives the encoding's K slots, all padded.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, NamedTuple

import numpy as np
import torch

from socialnav.sim.obstacle_points import ObstaclePoints, append_obstacle_agents

__all__ = [
    "LookaheadInputs",
    "encode_observation",
    "encode_state_arrays",
    "lookahead_inputs",
    "observation_field",
    "static_slots",
    "to_tensor",
]


class LookaheadInputs(NamedTuple):
    """One observation as tensors on the policy's device."""

    robot: torch.Tensor
    """(B, 9) robot states (float64 for NumPy input, the input's floating type for a tensor)."""
    humans: torch.Tensor
    """(B, N, 5) human states, obstacle points last; one padded slot when the input has none."""
    mask: torch.Tensor
    """(B, N) bool: real humans and real points."""
    next_humans: torch.Tensor | None
    """(B, N, 5) the simulator's next human states (the ``oracle``), the points appended; else None."""
    dt: float
    """The step [s]: the observation's, else the policy's."""
    as_numpy: bool
    """Whether the observation was NumPy (results go back as NumPy)."""
    static: int
    """How many trailing slots of ``humans`` are obstacle points."""


def observation_field(obs: Any, name: str) -> Any:
    """Field ``name`` of an observation given as an object or as a mapping."""
    if isinstance(obs, Mapping):
        return obs[name]
    return getattr(obs, name)


def static_slots(obs: Any) -> int:
    """How many trailing human slots of ``obs`` are obstacle points (0 when it says nothing)."""
    value = obs.get("static_slots", 0) if isinstance(obs, Mapping) else getattr(obs, "static_slots", 0)
    return int(value or 0)


def encode_state_arrays(
    robot: np.ndarray, humans: np.ndarray, mask: np.ndarray, maps: Any, encoding: ObstaclePoints | None
) -> tuple[np.ndarray, np.ndarray]:
    """Raw state arrays with the obstacle points of ``maps`` appended.

    Args:
        robot: (B, 9) robot states.
        humans: (B, N, 5) human states.
        mask: (B, N) real humans.
        maps: (B,) StaticMap or None each (None: open floors).
        encoding: The policy's obstacle encoding; None returns ``humans`` and ``mask`` unchanged.

    Returns:
        Humans (B, N + K, 5) and mask (B, N + K).
    """
    if encoding is None:
        return humans, mask
    return append_obstacle_agents(robot, humans, mask, maps, encoding)


def encode_observation(obs: Any, encoding: ObstaclePoints | None) -> Any:
    """``obs`` with the obstacle encoding's point slots appended and ``static_slots`` set.

    Without an encoding ``obs`` itself is returned; so is an observation already encoded, or one given
    as a mapping (a mapping carries its points already, if any).

    Args:
        obs: An :class:`~socialnav.sim.observation.Observation` (a dataclass).
        encoding: The policy's obstacle encoding, or None.

    Returns:
        The encoded observation (a copy), or ``obs``.
    """
    if encoding is None or isinstance(obs, Mapping) or static_slots(obs):
        return obs
    walls = getattr(obs, "obstacles", None)
    humans, mask = encode_state_arrays(
        obs.robot, obs.humans, obs.human_mask, None if walls is None else walls.maps, encoding
    )
    nxt = obs.next_humans
    if nxt is not None:  # the oracle's next humans, with the points where they are now
        nxt = np.concatenate([nxt, humans[:, nxt.shape[1]:]], axis=1)
    return dataclasses.replace(obs, humans=humans, human_mask=mask, next_humans=nxt,
                               static_slots=encoding.count)


def to_tensor(x: Any, device: torch.device, dtype: torch.dtype = torch.float64) -> torch.Tensor:
    """``x`` (array-like or tensor) as a tensor of ``dtype`` on ``device``."""
    return torch.as_tensor(np.asarray(x) if not torch.is_tensor(x) else x, device=device).to(dtype)


def lookahead_inputs(obs: Any, next_humans: Any, device: torch.device, default_dt: float) -> LookaheadInputs:
    """An (already encoded) observation and the oracle's next human states as tensors.

    Args:
        obs: Observation-like (attributes or keys ``robot``, ``humans``, ``human_mask``, optional
            ``dt`` and ``static_slots``), NumPy or torch.
        next_humans: (B, N, 5) exact next human states, or None; without the obstacle points, which
            are appended here (they do not move).
        device: Where the tensors go.
        default_dt: The step when the observation carries none [s].

    Returns:
        The tensors and what the lookahead needs to know about them.
    """
    static = static_slots(obs)
    robot_in = observation_field(obs, "robot")
    as_numpy = not torch.is_tensor(robot_in)
    geo = torch.float64
    if not as_numpy and robot_in.is_floating_point():
        geo = robot_in.dtype
    robot = to_tensor(robot_in, device, geo)
    humans = to_tensor(observation_field(obs, "humans"), device, geo)
    mask = to_tensor(observation_field(obs, "human_mask"), device, torch.bool)
    dt = obs.get("dt", None) if isinstance(obs, Mapping) else getattr(obs, "dt", None)
    dt = default_dt if dt is None else float(dt)
    nh = None if next_humans is None else to_tensor(next_humans, device, geo)
    if nh is not None and static and nh.shape[1] == humans.shape[1] - static:
        nh = torch.cat([nh, humans[:, -static:]], dim=1)  # the points do not move
    if humans.shape[1] == 0:  # no human slot at all: one padded slot keeps shapes non-empty
        humans = torch.zeros(humans.shape[0], 1, 5, dtype=geo, device=device)
        mask = torch.zeros(humans.shape[0], 1, dtype=torch.bool, device=device)
        nh = None if nh is None else humans.clone()
    return LookaheadInputs(robot, humans, mask, nh, dt, as_numpy, static)
