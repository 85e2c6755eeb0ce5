"""The mathematics of PPO, kept once.

Generalised advantage estimation, the clipped objective and the Gaussian log-density.

References: J. Schulman, P. Moritz, S. Levine, M. Jordan, P. Abbeel, "High-Dimensional Continuous Control
Using Generalized Advantage Estimation", ICLR 2016 (GAE); J. Schulman, F. Wolski, P. Dhariwal, A. Radford,
O. Klimov, "Proximal Policy Optimization Algorithms", arXiv 1707.06347, 2017 (clipped surrogate, value
clipping as in its reference implementation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    dones: torch.Tensor,
    last_value: torch.Tensor,
    gamma: float,
    lam: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Advantages and returns of a (T, B) rollout.

    ``dones[t]`` is True where the episode ended with step t (its next state is not bootstrapped:
    a timeout's bootstrap value is added to its reward by the caller); ``last_value`` (B,) is the
    value of the state after the last step.

        δ_t = r_t + γ V_{t+1} (1 − d_t) − V_t,   A_t = δ_t + γ λ (1 − d_t) A_{t+1},   R_t = A_t + V_t
    """
    t_len = rewards.shape[0]
    adv = torch.zeros_like(rewards)
    running = torch.zeros_like(last_value)
    for t in reversed(range(t_len)):
        next_value = last_value if t == t_len - 1 else values[t + 1]
        keep = 1.0 - dones[t].to(rewards.dtype)
        delta = rewards[t] + gamma * next_value * keep - values[t]
        running = delta + gamma * lam * keep * running
        adv[t] = running
    return adv, adv + values


def gaussian_log_prob(x: torch.Tensor, mean: torch.Tensor, log_std: torch.Tensor) -> torch.Tensor:
    """Log-density of a diagonal Gaussian, summed over the last axis."""
    z = (x - mean) * torch.exp(-log_std)
    return (-0.5 * z.square() - log_std - LOG_SQRT_2PI).sum(-1)


def gaussian_entropy(log_std: torch.Tensor) -> torch.Tensor:
    """Entropy of a diagonal Gaussian (depends only on σ)."""
    return (log_std + 0.5 + LOG_SQRT_2PI).sum(-1)


@dataclass(frozen=True)
class PPOLoss:
    """The minimised loss and its parts (the parts detached, for the curves)."""

    total: torch.Tensor
    policy: torch.Tensor
    value: torch.Tensor
    entropy: torch.Tensor
    approx_kl: torch.Tensor  # (r − 1) − log r, averaged (Schulman's low-variance estimator)
    clip_fraction: torch.Tensor


def ppo_loss(
    new_log_prob: torch.Tensor,
    old_log_prob: torch.Tensor,
    advantages: torch.Tensor,
    new_value: torch.Tensor,
    old_value: torch.Tensor,
    returns: torch.Tensor,
    entropy: torch.Tensor,
    *,
    clip: float,
    value_clip: float | None,
    value_coef: float,
    entropy_coef: float,
    normalize_advantages: bool,
) -> PPOLoss:
    """Clipped surrogate + value loss − entropy bonus, averaged over the samples.

        r = exp(log π_new − log π_old),   L_π = mean(max(−A r, −A clip(r, 1 − ε, 1 + ε)))
        L_V = ½ mean((V − R)²), or with value clipping
              ½ mean(max((V − R)², (V_old + clip(V − V_old, ±ε_V) − R)²))
        L   = L_π + c_V L_V − c_H mean(H)

    ``normalize_advantages`` standardises A over the minibatch first (std with Bessel's correction;
    a minibatch of one sample is only centred).
    """
    if normalize_advantages:
        centred = advantages - advantages.mean()
        advantages = centred / (advantages.std() + 1e-8) if advantages.numel() > 1 else centred
    log_ratio = new_log_prob - old_log_prob
    ratio = log_ratio.exp()
    surrogate = torch.max(-advantages * ratio, -advantages * ratio.clamp(1.0 - clip, 1.0 + clip))
    policy_loss = surrogate.mean()
    err = (new_value - returns).square()
    if value_clip is not None:
        clipped = old_value + (new_value - old_value).clamp(-value_clip, value_clip)
        err = torch.max(err, (clipped - returns).square())
    value_loss = 0.5 * err.mean()
    entropy_mean = entropy.mean()
    total = policy_loss + value_coef * value_loss - entropy_coef * entropy_mean
    with torch.no_grad():
        approx_kl = ((ratio - 1.0) - log_ratio).mean()
        clip_fraction = ((ratio - 1.0).abs() > clip).to(ratio.dtype).mean()
    return PPOLoss(
        total, policy_loss.detach(), value_loss.detach(), entropy_mean.detach(), approx_kl, clip_fraction
    )


def explained_variance(values: torch.Tensor, returns: torch.Tensor) -> float:
    """1 − Var(R − V) / Var(R) (NaN when the returns do not vary)."""
    var = float(returns.var(unbiased=False))
    return math.nan if var == 0 else 1.0 - float((returns - values).var(unbiased=False)) / var
