"""CrowdSim's discrete action set, batched over episodes.

The set is the one every learned baseline of CrowdNav scores (Chen et al., "Crowd-Robot Interaction:
Crowd-aware Robot Navigation with Attention-based Deep Reinforcement Learning", ICRA 2019): a stop
action followed by ``rotation_samples`` headings/rotations × ``speed_samples`` speeds, 81 actions with
the defaults.

Layout (same as CrowdNav's ``itertools.product(rotations, speeds)``): index 0 is stop, and action
``1 + k * speed_samples + i`` pairs heading/rotation ``k`` with speed ``i``; speed ``i`` is
``(exp((i + 1) / speed_samples) - 1) / (e - 1) * v_pref`` (≈ 0.129, 0.286, 0.479, 0.713, 1.0 × v_pref).

- Holonomic: world-frame velocities ``(v cos h_k, v sin h_k)`` with ``h_k = k * 2π / rotation_samples``.
- Unicycle: ``(v, dθ_k)``. CrowdNav uses ``linspace(-limit, limit, 16)``, which has no ``dθ = 0`` (16
  evenly spaced values symmetric about 0 cannot contain 0). The simulator contract requires straight
  motion to be available, so we use the evenly spaced grid ``dθ_k = -limit + k * 2 * limit /
  rotation_samples`` for ``k = 0 .. rotation_samples - 1``: step ``2 * limit / rotation_samples``
  (π/32 with the defaults), from ``-limit`` up to ``limit - step``; it contains ``dθ = 0`` exactly at
  ``k = rotation_samples / 2`` (``rotation_samples`` must be even). The set is therefore one step
  asymmetric (no ``+limit`` turn); this is the one deliberate deviation from CrowdNav.
"""

from __future__ import annotations

import math
from typing import Literal

import torch

from socialnav.sim.settings import HEADED_KINEMATICS

Kinematics = Literal["holonomic", "unicycle", "diff_drive"]

__all__ = ["Kinematics", "discrete_actions", "speed_fractions", "headings", "num_actions"]


def num_actions(speed_samples: int = 5, rotation_samples: int = 16) -> int:
    """Number of discrete actions: ``1 + speed_samples * rotation_samples`` (81 by default)."""
    return 1 + speed_samples * rotation_samples


def speed_fractions(
    speed_samples: int = 5, *, dtype: torch.dtype = torch.float64, device: torch.device | str | None = None
) -> torch.Tensor:
    """Exponentially spaced speeds as fractions of v_pref.

    Returns:
        (speed_samples,) ``(exp((i + 1) / S) - 1) / (e - 1)`` for ``i = 0 .. S - 1``; the last is 1.
    """
    i = torch.arange(1, speed_samples + 1, dtype=dtype, device=device)
    return torch.expm1(i / speed_samples) / (math.e - 1.0)


def headings(
    kinematics: Kinematics,
    rotation_samples: int = 16,
    rotation_limit: float = math.pi / 4,
    *,
    dtype: torch.dtype = torch.float64,
    device: torch.device | str | None = None,
) -> torch.Tensor:
    """World-frame headings (holonomic) or heading changes (unicycle) of the action set [rad].

    Returns:
        (rotation_samples,) see the module docstring.
    """
    k = torch.arange(rotation_samples, dtype=dtype, device=device)
    if kinematics == "holonomic":
        return k * (2.0 * math.pi / rotation_samples)
    if kinematics in HEADED_KINEMATICS:  # a differential drive takes the unicycle's commands
        if rotation_samples % 2:
            raise ValueError(
                f"rotation_samples must be even so that dθ = 0 is in the set, got {rotation_samples}"
            )
        step = 2.0 * rotation_limit / rotation_samples
        out = k * step - rotation_limit
        out[rotation_samples // 2] = 0.0  # exactly zero, not a rounding residue
        return out
    raise ValueError(f"unknown kinematics {kinematics!r}; expected 'holonomic', 'unicycle' or 'diff_drive'")


def discrete_actions(
    kinematics: Kinematics,
    v_pref: torch.Tensor,
    rotation_limit: float = math.pi / 4,
    speed_samples: int = 5,
    rotation_samples: int = 16,
) -> torch.Tensor:
    """CrowdSim's discrete action set for every episode of a batch.

    Args:
        kinematics: "holonomic" or "unicycle".
        v_pref: (B,) robot preferred speeds [m/s].
        rotation_limit: largest heading change of the unicycle set [rad]; unused when holonomic.
        speed_samples: number of non-zero speeds.
        rotation_samples: number of headings (holonomic) or rotations (unicycle).

    Returns:
        (B, 1 + speed_samples * rotation_samples, 2): holonomic (vx, vy) [m/s] in the world frame, or
        unicycle (v [m/s], dθ [rad]); index 0 is stop.
    """
    v_pref = torch.as_tensor(v_pref)
    if not v_pref.is_floating_point():
        v_pref = v_pref.to(torch.float64)
    dtype, device = v_pref.dtype, v_pref.device
    b = v_pref.shape[0]
    fr = speed_fractions(speed_samples, dtype=dtype, device=device)  # (S,)
    hd = headings(kinematics, rotation_samples, rotation_limit, dtype=dtype, device=device)  # (R,)
    speeds = v_pref[:, None, None] * fr[None, None, :]  # (B, 1, S)
    out = torch.zeros(b, num_actions(speed_samples, rotation_samples), 2, dtype=dtype, device=device)
    if kinematics == "holonomic":
        vx = speeds * torch.cos(hd)[None, :, None]  # (B, R, S)
        vy = speeds * torch.sin(hd)[None, :, None]
        out[:, 1:, 0] = vx.reshape(b, -1)
        out[:, 1:, 1] = vy.reshape(b, -1)
    else:
        out[:, 1:, 0] = speeds.expand(b, rotation_samples, speed_samples).reshape(b, -1)
        out[:, 1:, 1] = hd[None, :, None].expand(b, rotation_samples, speed_samples).reshape(b, -1)
    return out
