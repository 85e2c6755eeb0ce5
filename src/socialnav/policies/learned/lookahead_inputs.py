"""An observation as the value policy's lookahead reads it: obstacle points appended, then tensors.

:class:`~socialnav.policies.learned.value_policy.ValuePolicy` accepts an
:class:`~socialnav.sim.observation.Observation`, any object with its attributes, or a mapping with its
keys (a Gymnasium dict observation), as NumPy arrays or torch tensors. This module turns each into one
form: the robot (B, 9), human (B, N, 5) and mask (B, N) tensors on the policy's device, the step
``dt``, and the number of trailing slots that are obstacle points (``static_slots``).

The agents are the composition of the network's observation parts (``LearnedPolicySpec.observation_parts``,
by default :data:`~socialnav.sim.parts.NETWORK_PARTS`: the robot, the humans, the obstacle points), each
part's agents computed by the part (:meth:`~socialnav.sim.parts.ObservationPart.agents`), in part order.
Obstacles (:mod:`socialnav.sim.obstacle_points`): with an obstacle encoding, the nearest points of the
episode's obstacle outlines are appended after the human slots as standing agents, so the networks read
them like humans. An open floor gives the encoding's K slots, all padded.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np
import torch

from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.sim.parts.base import NETWORK_PARTS, PartContext, PartInput
from socialnav.sim.parts.composition import ObservationComposition
from socialnav.sim.parts.registry import get_observation_part

__all__ = [
    "LookaheadInputs",
    "network_composition",
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


@functools.lru_cache(maxsize=64)
def network_composition(
    encoding: ObstaclePoints | None, parts: Sequence[str] = NETWORK_PARTS
) -> ObservationComposition:
    """The networks' composition of ``parts``: the robot's state and sets of agents, ``encoding``'s points.

    Raises:
        ValueError: ``parts`` lacks ``robot``, names a part that is not a set of agents, or lists a moving
            set after a static one.
        UnknownObservationPartError: A name no part has.
    """
    parts = tuple(parts)
    if "robot" not in parts:
        raise ValueError(f"observation parts {list(parts)} of a network lack 'robot' (its state is what the "
                         "lookahead propagates)")
    # what the networks can read is decided by the parts' kinds, before any part lays itself out (a
    # sensor part would otherwise complain of the world it lacks, which no world setting can fix)
    found = [get_observation_part(name) for name in parts]
    other = [p.name for p in found if p.name != "robot" and not p.is_agent_set]
    if other:
        raise ValueError(f"observation part(s) {', '.join(other)} of a network are not sets of agents: the "
                         "value and PPO networks read the robot's state and sets of agents only")
    seen_static = None
    for part in found:
        if part.name == "robot":
            continue
        if part.static:
            seen_static = seen_static or part.name
        elif seen_static:
            raise ValueError(f"observation part {part.name!r} of a network moves and comes after the static "
                             f"{seen_static!r}: static agents (obstacle points) must come last")
    return ObservationComposition(parts, PartContext.for_networks(encoding))


def encode_state_arrays(
    robot: np.ndarray, humans: np.ndarray, mask: np.ndarray, maps: Any, encoding: ObstaclePoints | None,
    parts: Sequence[str] = NETWORK_PARTS,
) -> tuple[np.ndarray, np.ndarray]:
    """Raw state arrays as the network's agents: the humans, then the other parts' (the points of ``maps``).

    Args:
        robot: (B, 9) robot states.
        humans: (B, N, 5) human states.
        mask: (B, N) real humans.
        maps: (B,) StaticMap or None each (None: open floors).
        encoding: The policy's obstacle encoding; None (with the default parts) returns ``humans`` and
            ``mask`` unchanged.
        parts: The network's observation parts (:func:`network_composition`).

    Returns:
        Agents (B, N + K, 5) and their mask (B, N + K).
    """
    parts = tuple(parts)
    if encoding is None and parts == NETWORK_PARTS:
        return humans, mask
    data = PartInput(np.asarray(robot, dtype=np.float64), humans, mask, maps)
    agents, agent_mask, _ = network_composition(encoding, parts).agent_sets(data)
    return agents, agent_mask


def encode_observation(
    obs: Any, encoding: ObstaclePoints | None, parts: Sequence[str] = NETWORK_PARTS
) -> Any:
    """``obs`` with the network's agents (the humans, then the obstacle points) and ``static_slots`` set.

    Without an encoding (and with the default parts) ``obs`` itself is returned; so is an observation
    already encoded, or one given as a mapping (a mapping carries its points already, if any).

    Args:
        obs: An :class:`~socialnav.sim.observation.Observation` (a dataclass).
        encoding: The policy's obstacle encoding, or None.
        parts: The network's observation parts (:func:`network_composition`).

    Returns:
        The encoded observation (a copy), or ``obs``.
    """
    parts = tuple(parts)
    if (encoding is None and parts == NETWORK_PARTS) or isinstance(obs, Mapping) or static_slots(obs):
        return obs
    walls = getattr(obs, "obstacles", None)
    data = PartInput(np.asarray(obs.robot, dtype=np.float64), obs.humans, obs.human_mask,
                     None if walls is None else walls.maps, walls, observation=obs)
    humans, mask, static = network_composition(encoding, parts).agent_sets(data)
    if humans is obs.humans and not static:
        return obs
    nxt = obs.next_humans
    if nxt is not None:  # the oracle's next humans, with the other agents where they are now
        nxt = np.concatenate([nxt, humans[:, nxt.shape[1]:]], axis=1)
    return dataclasses.replace(obs, humans=humans, human_mask=mask, next_humans=nxt, static_slots=static)


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
