"""Registry entries of the learned policies; torch is imported only when one is built.

A learned policy is built from a checkpoint written by ``socialnav train``. The checkpoint's config
holds ``value_policy`` (kinematics, gamma, information, rotation_limit, dt and the reward constants)
so that the evaluator scores candidate actions exactly as the trainer did.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from socialnav.policies.base import register_policy
from socialnav.sim.observation import Observation

_DESCRIPTIONS = {
    "cadrl": "CADRL value network (Chen et al., ICRA 2017), one-step lookahead",
    "lstm_rl": "LSTM value network in the spirit of GA3C-CADRL (Everett et al., IROS 2018), value-based",
    "ga3c_cadrl": "alias of lstm_rl: an LSTM value network, not the A3C policy-gradient original",
    "sarl": "SARL: attention over humans (Chen et al., ICRA 2019), one-step lookahead",
    "om_sarl": "OM-SARL: SARL with local occupancy maps (Chen et al., ICRA 2019)",
    "rgl": "RGL: relational graph value network (Chen et al., IROS 2020), one-step lookahead",
    "mp_rgl": "model-predictive RGL: learned state predictor, d-step w-wide planning (Chen et al., IROS 2020)",
}


class LearnedPolicy:
    """A trained value network acting greedily through one-step lookahead (batched).

    Args:
        name: Registered policy name.
        value_policy: The :class:`socialnav.policies.learned.ValuePolicy` to act with.
        checkpoint: Where the network came from (recorded with results).
    """

    def __init__(self, name: str, value_policy: Any, checkpoint: Path | None = None):
        self.name = name
        self.value_policy = value_policy
        self.information = value_policy.information
        self.checkpoint = checkpoint

    def act(self, observation: Observation) -> np.ndarray:
        if self.information == "oracle" and observation.next_humans is None:
            raise ValueError(
                f"policy {self.name!r} uses oracle information: observe the world with oracle=True"
            )
        actions = np.zeros((observation.batch_size, 2))
        rows = np.flatnonzero(observation.active)
        if rows.size == 0:
            return actions
        # Only episodes whose robot still acts are scored: parked robots (M_III continuation) and
        # idle slots would otherwise cost a full lookahead each.
        obs = observation if rows.size == observation.batch_size else observation.take(rows)
        _, chosen = self.value_policy.act(
            obs, next_humans=obs.next_humans if self.information == "oracle" else None
        )
        actions[rows] = np.asarray(chosen, dtype=np.float64)
        return actions

    def describe(self) -> dict[str, Any]:
        vp = self.value_policy
        return {
            "policy": self.name,
            "information": self.information,
            "checkpoint": None if self.checkpoint is None else str(self.checkpoint),
            "planning_depth": vp.planning_depth,
            "planning_width": vp.planning_width,
            "reward_rule": vp.reward_rule,
        }


def load_learned_policy(
    name: str,
    checkpoint: str | Path,
    information: str | None = None,
    device: str = "cpu",
    planning_depth: int | None = None,
    planning_width: int | None = None,
) -> LearnedPolicy:
    """Loads ``checkpoint`` (refusing one of another policy or input size) into a LearnedPolicy.

    ``information``, ``planning_depth`` and ``planning_width`` override the checkpoint's settings
    (None keeps them); ``learned`` needs a checkpoint that stores a state predictor.
    """
    from socialnav.policies.learned import ValuePolicy, load_checkpoint
    from socialnav.policies.learned.state import RewardParams

    ckpt = load_checkpoint(checkpoint, name, map_location=device)
    settings = dict(ckpt.config.get("value_policy", {}))
    reward = RewardParams(**settings.pop("reward", {}))
    for key, value in (
        ("information", information),
        ("planning_depth", planning_depth),
        ("planning_width", planning_width),
    ):
        if value is not None:
            settings[key] = value
    if settings.get("information") == "learned" and ckpt.predictor is None:
        raise ValueError(
            f"checkpoint {checkpoint} stores no state predictor, so information 'learned' is not available "
            "(train with --information learned, or --policy mp_rgl)"
        )
    ckpt.model.eval()
    policy = ValuePolicy(ckpt.model, reward_params=reward, device=device, predictor=ckpt.predictor, **settings)
    return LearnedPolicy(name, policy, Path(checkpoint))


def _factory(name: str):
    def make(
        checkpoint: Path,
        preset: Any = None,
        information: str | None = None,
        device: str = "cpu",
        planning_depth: int | None = None,
        planning_width: int | None = None,
        **_: Any,
    ) -> LearnedPolicy:
        return load_learned_policy(name, checkpoint, information, device, planning_depth, planning_width)

    return make


for _name, _description in _DESCRIPTIONS.items():
    register_policy(
        _name,
        description=_description,
        learned=True,
        parameters={
            "information": "learned" if _name == "mp_rgl" else "constant_velocity",
            "device": "cpu",
            "planning_depth": 2 if _name == "mp_rgl" else 1,
            "planning_width": 2 if _name == "mp_rgl" else 1,
        },
    )(_factory(_name))
