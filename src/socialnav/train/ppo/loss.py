"""PPO's loss (Schulman et al., "Proximal Policy Optimization Algorithms", 2017).

The clipped surrogate, the (optionally clipped) value loss and the entropy bonus, with the diagonal
Gaussian's log-density and entropy they are computed from. The trainer
(:mod:`socialnav.train.ppo.algorithm`) calls them per minibatch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

__all__ = ["PPOLoss", "gaussian_entropy", "gaussian_log_prob", "ppo_loss"]

LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


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
