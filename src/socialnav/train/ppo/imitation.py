"""A PPO run's warm start by imitation: DAgger from a planner, then the policy gradient.

The value-based baselines start from ORCA's demonstrations (CrowdNav, RGL); PPO starts from a random
network, which on a walled suite must find doors and corridors by chance. With ``imitation_updates``
the schedule's first updates fit the network to a planner (``imitation_teacher``, ``orca_route`` by
default) instead, in the manner of DAgger: in update u of the U imitation updates, each environment's
step is the teacher's with probability β = 1 − u / U and the network's (its mean action) otherwise, and
the network fits the teacher's action in every state visited, so that it learns to recover from the
states its own mistakes lead to. The loss is the Gaussian policy's negative log-likelihood of the
teacher's action (its σ follows the network's remaining error) plus the value loss on the rollout's
returns, so that the critic knows the policy it hands to PPO. The imitation updates may have their own
learning rate, passes and minibatches (``imitation_lr``, ``_epochs``, ``_minibatches``: supervised
learning wants more and larger steps than a policy-gradient update); the updates after them are PPO's,
and counters, validation and checkpoints run through both.

The teacher sees what the evaluated planner sees: the world's exact observation with its walls, never
the network's sensors. Every draw comes from the run's action generator, which ``last.pt`` saves, so a
resumed run goes on bit for bit.

References: S. Ross, G. Gordon, J. A. Bagnell, "A Reduction of Imitation Learning and Structured
Prediction to No-Regret Online Learning", AISTATS 2011 (DAgger, its mixture β).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from socialnav.policies.learned.attn_graph import squash_actions, trained_action_squash
from socialnav.train.ppo.loss import PPOLoss, gaussian_entropy, gaussian_log_prob

if TYPE_CHECKING:
    from socialnav.presets import Preset
    from socialnav.train.ppo.settings import PPOSettings

__all__ = ["build_teacher", "imitation_actions", "imitation_loss", "teacher_share", "teacher_steps",
           "unsquash_actions"]


def build_teacher(settings: PPOSettings, preset: Preset) -> Any | None:
    """The planner the run imitates first (the preset's parameters for it), or None without imitation."""
    if settings.imitation_updates == 0:
        return None
    from socialnav.policies.building import build_policy

    return build_policy(settings.imitation_teacher, preset)


def teacher_share(update: int, imitation_updates: int) -> float:
    """DAgger's β: the share of steps the teacher takes in the rollout of update ``update + 1``.

    1 in the first imitation update, falling linearly to 1/U in the last (U = ``imitation_updates``),
    0 in PPO's updates.
    """
    if update >= imitation_updates:
        return 0.0
    return 1.0 - update / imitation_updates


def teacher_steps(beta: float, n_envs: int, generator: torch.Generator) -> np.ndarray:
    """(n_envs,) bool: the environments whose step the teacher takes (each with probability ``beta``).

    No draw at β = 1 or 0, so a run's generator is used only where the mixture is a real one.
    """
    if beta >= 1.0:
        return np.ones(n_envs, dtype=bool)
    if beta <= 0.0:
        return np.zeros(n_envs, dtype=bool)
    return (torch.rand(n_envs, generator=generator, dtype=torch.float64) < beta).numpy()


def unsquash_actions(action: np.ndarray, squash: str, v_pref: np.ndarray, rotation_limit: float,
                     max_reverse_speed: float = 0.0) -> np.ndarray:
    """A raw Gaussian value that ``attn_graph.squash_actions`` maps to ``action`` (the teacher's label).

    ``radial``: the action itself (the teacher's speed is at most v_pref, where the squash is the
    identity; a faster one is scaled onto the disc first). ``span``: v from [-max_reverse_speed, v_pref]
    and dθ from [-rotation_limit, rotation_limit] back to [-1, 1]. ``clip``: the action itself.

    Args:
        action: (B, 2) world actions.
        squash: the network's action squash.
        v_pref: (B,) the robots' preferred speeds [m/s].
        rotation_limit: the largest heading change per step [rad].
        max_reverse_speed: a differential drive's reverse speed [m/s].

    Returns:
        (B, 2) raw values, float64.
    """
    action = np.asarray(action, dtype=np.float64)
    v_pref = np.asarray(v_pref, dtype=np.float64)
    if squash == "radial":  # the radial squash is its own inverse on the disc
        return squash_actions(action, "holonomic", v_pref, rotation_limit, squash="radial")
    if squash == "span":
        u0 = 2.0 * (action[:, 0] + max_reverse_speed) / (v_pref + max_reverse_speed) - 1.0
        u1 = action[:, 1] / rotation_limit
        return np.clip(np.stack([u0, u1], 1), -1.0, 1.0)
    if squash == "clip":
        return action.copy()
    raise ValueError(f"squash must be 'radial', 'span' or 'clip', got {squash!r}")


def imitation_loss(mean: torch.Tensor, log_std: torch.Tensor, teacher_raw: torch.Tensor, value: torch.Tensor,
                   returns: torch.Tensor, value_coef: float) -> PPOLoss:
    """Behaviour cloning's loss: −log π(teacher's action) + c_V · ½ mean((V − R)²).

    The parts are reported in PPO's columns (``policy``: the negative log-likelihood); the ratio's
    diagnostics, which an imitation update has not, are 0.
    """
    nll = -gaussian_log_prob(teacher_raw, mean, log_std).mean()
    value_loss = 0.5 * (value - returns).square().mean()
    zero = torch.zeros((), device=mean.device)
    return PPOLoss(nll + value_coef * value_loss, nll.detach(), value_loss.detach(),
                   gaussian_entropy(log_std).detach(), zero, zero)


def imitation_actions(teacher: Any, obs: Any, mean: torch.Tensor, beta: float, generator: torch.Generator,
                      kinematics: str, rotation_limit: float, max_reverse_speed: float
                      ) -> tuple[torch.Tensor, np.ndarray]:
    """One imitation step: the teacher's action as the network's label, and the actions the worlds take.

    Args:
        teacher: the planner (acts on the worlds' exact observation).
        obs: the observation the step acts on.
        mean: (B, 2) the network's mean (raw) actions.
        beta: the teacher's share of the steps (:func:`teacher_share`).
        generator: the run's action generator (which environments the teacher steps).
        kinematics: the robot's kinematics.
        rotation_limit: the largest heading change per step [rad].
        max_reverse_speed: a differential drive's reverse speed [m/s] (0 otherwise).

    Returns:
        The (B, 2) raw labels (as ``mean``) and the (B, 2) world actions: the teacher's where it steps,
        the network's mean action squashed elsewhere.
    """
    v_pref = obs.robot[:, 7]
    taught = np.asarray(teacher.act(obs), dtype=np.float64)
    squash = trained_action_squash(kinematics)
    label = unsquash_actions(taught, squash, v_pref, rotation_limit, max_reverse_speed)
    own = squash_actions(mean.double().cpu().numpy(), kinematics, v_pref, rotation_limit, max_reverse_speed)
    by_teacher = teacher_steps(beta, len(own), generator)
    action = np.where(by_teacher[:, None], taught, own)
    return torch.as_tensor(label, dtype=mean.dtype, device=mean.device), action
