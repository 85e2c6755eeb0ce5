"""What one batched World step returns: rewards, episode ends and the finished episodes' records.

The per-slot report is written by the core in its step pass as numeric codes; the names
(``outcome``, ``collision_kind``) are built on access, since most callers only read the numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from socialnav.sim.observation import Observation
from socialnav.sim.recorder import COLLISION_KIND_NAMES, OUTCOME_NAMES


@dataclass(frozen=True)
class StepResult:
    """What one batched step returns (arrays over the B slots).

    Attributes:
        reward: (B,) reward of the step (0 for idle slots).
        terminated: (B,) episode ended by success or collision in this step.
        truncated: (B,) episode ended by the time limit in this step.
        finished: trajectories of the episodes that ended in this step (empty when not recording).
        final_observation: observation of the finished slots before their reset (rows where done).
        outcome: (B,) "success", "collision" or "timeout" where an episode ended in this step, "" elsewhere.
        final_dmin: (B,) the finished episodes' robot-human clearance over their last step (the swept
            surface-to-surface distance of CrowdSim's info['dmin'], inf without humans; NaN elsewhere).
        final_episode: (B,) the finished episodes' indices (-1 elsewhere).
        outcome_code: (B,) int8 final status code where an episode ended (``_core.STATUS_*``; 0,
            running, elsewhere); ``outcome`` names it.
        observation: the observation after the step (``World.step(..., observe=True)`` only).
        collision_kind_code: (B,) int8 ``_core.COLLISION_*`` where an episode ended in a collision
            (1 human, 2 obstacle), 0 elsewhere; ``collision_kind`` names it.
    """

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    finished: list
    final_observation: Observation | None
    outcome_code: np.ndarray
    final_dmin: np.ndarray | None = None
    final_episode: np.ndarray | None = None
    observation: Observation | None = None
    collision_kind_code: np.ndarray | None = None

    @property
    def collision_kind(self) -> np.ndarray:
        """(B,) "human" or "obstacle" where an episode ended in a collision, "" elsewhere."""
        if self.collision_kind_code is None:
            return np.full(len(self.reward), "", dtype=object)
        return _COLLISION_KIND_BY_CODE[self.collision_kind_code]

    @property
    def outcome(self) -> np.ndarray:
        """(B,) "success", "collision" or "timeout" where an episode ended in this step, "" elsewhere."""
        return _OUTCOME_BY_STATUS[self.outcome_code]


#: Outcome name by final status code (an object array: one fancy-index per step, no Python loop).
_OUTCOME_BY_STATUS = np.array(
    [OUTCOME_NAMES.get(code, "") for code in range(max(OUTCOME_NAMES) + 1)], dtype=object
)
_COLLISION_KIND_BY_CODE = np.array(
    [COLLISION_KIND_NAMES.get(code, "") for code in range(max(COLLISION_KIND_NAMES) + 1)], dtype=object
)
