"""CrowdSim's discrete action set (docs/simulator.md), NumPy version for non-torch users."""

from __future__ import annotations

import math

import numpy as np

from socialnav.sim.settings import KINEMATICS


def action_speeds(v_pref: float, samples: int = 5) -> np.ndarray:
    """Exponentially spaced speeds (e^{(i+1)/5} - 1)/(e - 1)·v_pref, i = 0..samples-1 [m/s]."""
    i = np.arange(samples, dtype=float)
    return (np.exp((i + 1) / samples) - 1.0) / (math.e - 1.0) * v_pref


def discrete_actions(kinematics: str, v_pref: float, rotation_limit: float = math.pi / 4,
                     speed_samples: int = 5, rotation_samples: int = 16) -> np.ndarray:
    """The 1 + speeds × rotations action set; row 0 is stop.

    Holonomic rows are world-frame (vx, vy) with headings k·2π/16. Unicycle and diff_drive rows are (v, dθ)
    with 16 rotations spread evenly over [-limit, limit]; with an even count CrowdSim's
    ``np.linspace(-limit, limit, 16)`` misses dθ = 0, so the grid used here is
    ``linspace(-limit, limit, 17)`` without its last point, which keeps 0 and 16 rotations.

    Returns:
        (1 + speed_samples·rotation_samples, 2) array, equal to
        ``socialnav.policies.learned.actions.discrete_actions`` (tested).
    """
    if kinematics not in KINEMATICS:
        raise ValueError(f"kinematics must be 'holonomic', 'unicycle' or 'diff_drive', got {kinematics!r}")
    if not (math.isfinite(v_pref) and v_pref > 0):
        raise ValueError(f"v_pref must be a finite speed > 0 [m/s], got {v_pref!r}")
    if kinematics != "holonomic" and not (math.isfinite(rotation_limit) and rotation_limit > 0):
        raise ValueError(f"rotation_limit must be a finite angle > 0 [rad], got {rotation_limit!r}")
    if speed_samples < 1 or rotation_samples < 1:
        raise ValueError(f"speed_samples and rotation_samples must be >= 1, got {speed_samples}, "
                         f"{rotation_samples}")
    speeds = action_speeds(v_pref, speed_samples)
    # CrowdNav's order: heading-major, index = 1 + speed_samples * heading + speed.
    if kinematics == "holonomic":
        headings = np.arange(rotation_samples) * 2 * math.pi / rotation_samples
        h, s = np.meshgrid(headings, speeds, indexing="ij")
        rows = np.stack([s * np.cos(h), s * np.sin(h)], axis=-1).reshape(-1, 2)
    else:
        rotations = np.linspace(-rotation_limit, rotation_limit, rotation_samples + 1)[:-1]
        r, s = np.meshgrid(rotations, speeds, indexing="ij")
        rows = np.stack([s, r], axis=-1).reshape(-1, 2)
    return np.concatenate([np.zeros((1, 2)), rows], axis=0)
