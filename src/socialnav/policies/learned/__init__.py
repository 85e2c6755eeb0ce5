"""Learned navigation policies (PyTorch).

The value-based CADRL, LSTM-RL (GA3C-CADRL-style), SARL, OM-SARL, RGL and model-predictive RGL (with the
learned state predictor), and CrowdNav++'s attention-graph actor-critic trained with PPO (``crowdnav_pp``),
with a plain MLP actor-critic beside it (``ppo_mlp``).

The policies themselves are named by their registration records (:mod:`socialnav.policies.learned_catalog`);
:data:`LEARNED_POLICIES` (``networks.py``) maps each name to its network. See docs/policies_learned.md.
"""

from socialnav.policies.learned.actions import discrete_actions
from socialnav.policies.learned.attn_graph import AttnGraphNet
from socialnav.policies.learned.cadrl import CADRL
from socialnav.policies.learned.checkpoint import Checkpoint, load_checkpoint, save_checkpoint
from socialnav.policies.learned.lstm_rl import LSTMRL
from socialnav.policies.learned.networks import LEARNED_POLICIES, ValueNetwork, build
from socialnav.policies.learned.ppo_mlp import MLPActorCritic
from socialnav.policies.learned.predictor import StatePredictor
from socialnav.policies.learned.rgl import RGL, mp_rgl
from socialnav.policies.learned.sarl import SARL, om_sarl
from socialnav.policies.learned.state import (
    RewardParams,
    occupancy_map,
    propagate_humans_constant_velocity,
    propagate_robot,
    reward,
    rotate,
    swept_reward,
)
from socialnav.policies.learned.value_policy import ValuePolicy

__all__ = [
    "AttnGraphNet",
    "MLPActorCritic",
    "CADRL",
    "LSTMRL",
    "SARL",
    "om_sarl",
    "RGL",
    "mp_rgl",
    "StatePredictor",
    "ValueNetwork",
    "ValuePolicy",
    "RewardParams",
    "LEARNED_POLICIES",
    "build",
    "Checkpoint",
    "save_checkpoint",
    "load_checkpoint",
    "discrete_actions",
    "propagate_robot",
    "propagate_humans_constant_velocity",
    "rotate",
    "reward",
    "swept_reward",
    "occupancy_map",
]
