"""Pure batched lookahead: robot/human propagation, agent-centric joint state, reward, occupancy maps.

Everything here is a pure function of tensors (no environment), so a policy can score every candidate
action of every episode of a batch at once. The conventions follow CrowdNav's ``propagate``,
``rotate``, ``compute_reward`` and ``build_occupancy_maps`` (Chen et al., "Crowd-Robot Interaction:
Crowd-aware Robot Navigation with Attention-based Deep Reinforcement Learning", ICRA 2019), implemented
here from their description.

Column conventions (see docs/internals.md):
    robot (…, 9): px, py, vx, vy, radius, gx, gy, v_pref, theta
    humans (…, N, 5): px, py, vx, vy, radius
    joint state (…, N, 13): dg, v_pref, theta, radius, vx, vy | px1, py1, vx1, vy1, radius1, da, radius_sum
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from socialnav.policies.learned.actions import Kinematics
from socialnav.sim.observation import HUMAN_COLUMNS, HUMAN_DIM, ROBOT_COLUMNS, ROBOT_DIM
from socialnav.sim.settings import HEADED_KINEMATICS

__all__ = [
    "DiffDriveLimits",
    "ROBOT_DIM",
    "HUMAN_DIM",
    "JOINT_DIM",
    "SELF_DIM",
    "OM_DIM",
    "RewardParams",
    "propagate_robot",
    "propagate_humans_constant_velocity",
    "rotate",
    "reward",
    "swept_reward",
    "occupancy_map",
]

# The widths are socialnav.sim.observation's column tables (one definition): the state rows are the world
# frame's columns, the joint state the robot frame's robot columns followed by one human's.
SELF_DIM = len(ROBOT_COLUMNS["robot"])  # robot part of the joint state (6)
JOINT_DIM = SELF_DIM + len(HUMAN_COLUMNS["robot"])  # robot part (6) + human part (7)
OM_DIM = 48  # 4 x 4 cells x 3 channels (default occupancy map)


@dataclass(frozen=True)
class RewardParams:
    """CrowdSim's reward constants (recorded with every checkpoint).

    Attributes:
        success_reward: reward when the robot is within its radius of its goal.
        collision_penalty: reward when any clearance is negative.
        discomfort_dist: clearance below which the discomfort penalty applies [m].
        discomfort_penalty_factor: factor f of the discomfort penalty (dmin - discomfort_dist) * f * dt.
        time_step: dt used in the discomfort penalty [s].
    """

    success_reward: float = 1.0
    collision_penalty: float = -0.25
    discomfort_dist: float = 0.2
    discomfort_penalty_factor: float = 0.5
    time_step: float = 0.25


@dataclass(frozen=True)
class DiffDriveLimits:
    """A differential drive's limits, as the world applies them (docs/kinematics.md)."""

    max_linear_acceleration: float  # [m/s²]
    max_angular_acceleration: float  # [rad/s²]
    max_reverse_speed: float  # [m/s]
    rotation_limit: float  # [rad] per step

    @classmethod
    def of(cls, diff_drive: dict, rotation_limit: float) -> DiffDriveLimits:
        """From a ``diff_drive`` record (``DiffDriveSettings.to_dict()``) and the rotation limit."""
        return cls(float(diff_drive["max_linear_acceleration"]),
                   float(diff_drive["max_angular_acceleration"]), float(diff_drive["max_reverse_speed"]),
                   float(rotation_limit))


def propagate_robot(
    robot: torch.Tensor, actions: torch.Tensor, kinematics: Kinematics, dt: float,
    limits: DiffDriveLimits | None = None,
) -> torch.Tensor:
    """Next robot full state for each candidate action (CrowdNav's ``propagate`` for a FullState).

    Holonomic: velocity := (vx, vy) of the action, p += v·dt, heading unchanged.
    Unicycle: θ' = θ + dθ, v' = v (cos θ', sin θ'), p += v'·dt.
    Differential drive: the robot rows carry two more columns, the (v, ω) of the last step; the command
    is reached within the acceleration ``limits`` and the arc driven exactly, as the world does
    (cpp/world.cpp, ``diff_drive_velocity``), and the next rows carry the (v, ω) reached.

    Args:
        robot: (B, 9) robot full states ((B, 11) with v, ω for a differential drive).
        actions: (B, K, 2) actions, holonomic (vx, vy) [m/s] or unicycle / diff drive (v [m/s], dθ [rad]).
        kinematics: "holonomic", "unicycle" or "diff_drive".
        dt: time step [s].
        limits: a differential drive's limits (required for one).

    Returns:
        (B, K, 9) next robot full states ((B, K, 11) for a differential drive).

    Raises:
        ValueError: A differential drive without its limits or its (v, ω) columns.
    """
    k = actions.shape[-2]
    if kinematics == "diff_drive":
        return _propagate_diff_drive(robot, actions, dt, limits)
    nxt = robot.unsqueeze(-2).expand(*robot.shape[:-1], k, ROBOT_DIM).clone()
    if kinematics == "holonomic":
        vx, vy = actions[..., 0], actions[..., 1]
    elif kinematics == "unicycle":
        theta = nxt[..., 8] + actions[..., 1]
        vx = actions[..., 0] * torch.cos(theta)
        vy = actions[..., 0] * torch.sin(theta)
        nxt[..., 8] = theta
    else:
        raise ValueError(f"unknown kinematics {kinematics!r}; expected 'holonomic' or 'unicycle'")
    nxt[..., 0] = nxt[..., 0] + vx * dt
    nxt[..., 1] = nxt[..., 1] + vy * dt
    nxt[..., 2] = vx
    nxt[..., 3] = vy
    return nxt


def _propagate_diff_drive(robot: torch.Tensor, actions: torch.Tensor, dt: float,
                          limits: DiffDriveLimits | None) -> torch.Tensor:
    if limits is None or robot.shape[-1] != ROBOT_DIM + 2:
        raise ValueError("a diff_drive lookahead needs the robot's limits and its (v, ω) after its 9 columns")
    nxt = robot.unsqueeze(-2).expand(*robot.shape[:-1], actions.shape[-2], ROBOT_DIM + 2).clone()
    v_pref, v0, w0 = robot[..., 7:8], robot[..., 9:10], robot[..., 10:11]
    w_max = limits.rotation_limit / dt
    v_cmd = torch.minimum(actions[..., 0].clamp(min=-limits.max_reverse_speed), v_pref)
    w_cmd = (actions[..., 1] / dt).clamp(-w_max, w_max)
    dv, dw = limits.max_linear_acceleration * dt, limits.max_angular_acceleration * dt
    v = torch.minimum(torch.maximum(v_cmd, v0 - dv), v0 + dv)
    w = torch.minimum(torch.maximum(w_cmd, w0 - dw), w0 + dw)
    half = 0.5 * w * dt
    safe = torch.where(half == 0, torch.ones_like(half), half)
    chord = torch.where(half == 0, torch.ones_like(half), torch.sin(safe) / safe)  # sinc(ω·dt/2)
    heading = nxt[..., 8] + half
    vx, vy = v * chord * torch.cos(heading), v * chord * torch.sin(heading)
    nxt[..., 0] = nxt[..., 0] + vx * dt
    nxt[..., 1] = nxt[..., 1] + vy * dt
    nxt[..., 2], nxt[..., 3] = vx, vy
    nxt[..., 8] = nxt[..., 8] + w * dt
    nxt[..., 9], nxt[..., 10] = v, w
    return nxt


def propagate_humans_constant_velocity(humans: torch.Tensor, dt: float) -> torch.Tensor:
    """Humans' next observable states assuming they keep their current velocity.

    Args:
        humans: (…, N, 5) human observable states.
        dt: time step [s].

    Returns:
        (…, N, 5) with p += v·dt, velocity and radius unchanged.
    """
    nxt = humans.clone()
    nxt[..., 0:2] = humans[..., 0:2] + humans[..., 2:4] * dt
    return nxt


def rotate(
    robot: torch.Tensor,
    humans: torch.Tensor,
    kinematics: Kinematics = "holonomic",
    dtype: torch.dtype | None = None,
) -> torch.Tensor:
    """Agent-centric joint state of CrowdNav: x-axis from the robot towards its goal.

    With rot = atan2(gy - py, gx - px) and (c, s) = (cos rot, sin rot):
    dg = |g - p|; vx' = vx c + vy s; vy' = vy c - vx s; theta' = theta - rot (unicycle) or 0 (holonomic);
    px1 = (hx - px) c + (hy - py) s; py1 = (hy - py) c - (hx - px) s; vx1, vy1 rotated alike;
    radius1 = r_h; da = |h - p|; radius_sum = r + r_h.

    Args:
        robot: (…, 9) robot full states; broadcast against the leading dims of ``humans``.
        humans: (…, N, 5) human observable states.
        kinematics: decides the heading column (see above).
        dtype: dtype of the result (default: the inputs' promoted dtype). The values are computed
            in the inputs' dtype and rounded once when written, exactly as ``rotate(...).to(dtype)``, without
            building the joint state twice.

    Returns:
        (…, N, 13): dg, v_pref, theta, radius, vx, vy, px1, py1, vx1, vy1, radius1, da, radius_sum.
    """
    r = robot.unsqueeze(-2)  # (…, 1, 9)
    dx = r[..., 5] - r[..., 0]
    dy = r[..., 6] - r[..., 1]
    rot = torch.atan2(dy, dx)
    c, s = torch.cos(rot), torch.sin(rot)
    dg = torch.sqrt(dx * dx + dy * dy)
    vx = r[..., 2] * c + r[..., 3] * s
    vy = r[..., 3] * c - r[..., 2] * s
    theta = r[..., 8] - rot if kinematics in HEADED_KINEMATICS else torch.zeros_like(rot)
    hx = humans[..., 0] - r[..., 0]
    hy = humans[..., 1] - r[..., 1]
    px1 = hx * c + hy * s
    py1 = hy * c - hx * s
    vx1 = humans[..., 2] * c + humans[..., 3] * s
    vy1 = humans[..., 3] * c - humans[..., 2] * s
    r1 = humans[..., 4]
    da = torch.sqrt(hx * hx + hy * hy)
    self_part = torch.stack([dg, r[..., 7], theta, r[..., 4], vx, vy], dim=-1)  # (…, 1, 6)
    human_part = torch.stack(torch.broadcast_tensors(px1, py1, vx1, vy1, r1, da, r[..., 4] + r1), dim=-1)
    # Both parts are written into the result, converted on the way, the robot part broadcast over the
    # humans: no concatenated copy in the inputs' dtype and no second pass to convert it. (Writing the
    # 13 columns one by one saves one more pass on large batches but costs a single episode ~20 %
    # more in small operations.)
    dtype = dtype or torch.promote_types(robot.dtype, humans.dtype)
    out = torch.empty(*human_part.shape[:-1], JOINT_DIM, dtype=dtype, device=robot.device)
    out[..., :SELF_DIM] = self_part
    out[..., SELF_DIM:] = human_part
    return out


def reward(
    robot_next: torch.Tensor,
    humans_next: torch.Tensor,
    mask: torch.Tensor,
    params: RewardParams | None = None,
) -> torch.Tensor:
    """CrowdSim's reward evaluated on predicted next states (point clearance at the next state).

    Collision (min clearance < 0) → collision_penalty; else robot within its radius of its goal →
    success_reward; else dmin < discomfort_dist → (dmin - discomfort_dist) * factor * dt; else 0.
    Padded humans (mask False) are ignored; with no human only the goal term can fire.

    Args:
        robot_next: (…, 9) predicted robot states.
        humans_next: (…, N, 5) predicted human states (broadcast against ``robot_next``'s leading dims).
        mask: (…, N) bool, real humans.
        params: reward constants (default ``RewardParams()``).

    Returns:
        (…) rewards, in the dtype of ``robot_next``.
    """
    params = params if params is not None else RewardParams()
    r = robot_next.unsqueeze(-2)
    d = torch.sqrt((humans_next[..., 0] - r[..., 0]) ** 2 + (humans_next[..., 1] - r[..., 1]) ** 2)
    clearance = d - r[..., 4] - humans_next[..., 4]
    return _reward_from_clearance(clearance, mask, robot_next, params)


def _reward_from_clearance(
    clearance: torch.Tensor, mask: torch.Tensor, robot_next: torch.Tensor, params: RewardParams
) -> torch.Tensor:
    """CrowdSim's reward from per-human clearances (…, N) and the robot's next state (…, 9).

    Collision, else success at the goal, else discomfort, else 0; padded humans are ignored.
    """
    clearance = torch.where(mask, clearance, torch.full_like(clearance, float("inf")))
    if clearance.shape[-1] > 0:
        dmin = clearance.amin(dim=-1)
    else:
        dmin = torch.full_like(robot_next[..., 0], float("inf"))
    gx = robot_next[..., 0] - robot_next[..., 5]
    gy = robot_next[..., 1] - robot_next[..., 6]
    goal_d = torch.sqrt(gx * gx + gy * gy)
    zero = torch.zeros_like(dmin)
    disc = (dmin - params.discomfort_dist) * params.discomfort_penalty_factor * params.time_step
    out = torch.where(dmin < params.discomfort_dist, disc, zero)
    out = torch.where(goal_d < robot_next[..., 4], zero + params.success_reward, out)
    return torch.where(dmin < 0, zero + params.collision_penalty, out)


def swept_reward(
    robot: torch.Tensor,
    robot_next: torch.Tensor,
    humans: torch.Tensor,
    humans_next: torch.Tensor,
    mask: torch.Tensor,
    params: RewardParams | None = None,
) -> torch.Tensor:
    """The world's reward on a predicted step: swept collision and discomfort, goal at the end.

    Robot and humans move linearly over the step from their current to their next positions, as in
    the world (cpp/world.cpp): the clearance is the minimum distance between centres over the step
    minus the radii; collision when it is negative, else success when the robot ends within its
    radius of its goal, else the discomfort penalty when it is below ``discomfort_dist``.

    Args:
        robot: (B, 9) current robot states.
        robot_next: (B, K, 9) next robot states, one per candidate action.
        humans: (B, N, 5) current human states.
        humans_next: (B, N, 5) predicted next human states (shared by the K actions).
        mask: (B, N) bool, real humans.
        params: reward constants; ``params.time_step`` is the step length.

    Returns:
        (B, K) rewards.
    """
    params = params if params is not None else RewardParams()
    d0x = (humans[..., 0] - robot[..., 0:1]).unsqueeze(1)  # (B, 1, N)
    d0y = (humans[..., 1] - robot[..., 1:2]).unsqueeze(1)
    # Displacements over the step (positions, not velocities: a predictor's next velocity need not
    # be its displacement over dt, and the world sweeps what actually moves).
    rdx = (robot_next[..., 0] - robot[..., 0:1]).unsqueeze(-1)  # (B, K, 1)
    rdy = (robot_next[..., 1] - robot[..., 1:2]).unsqueeze(-1)
    hdx = (humans_next[..., 0] - humans[..., 0]).unsqueeze(1)  # (B, 1, N)
    hdy = (humans_next[..., 1] - humans[..., 1]).unsqueeze(1)
    ddx, ddy = hdx - rdx, hdy - rdy  # (B, K, N) relative displacement
    dd2 = ddx * ddx + ddy * ddy
    s = -(d0x * ddx + d0y * ddy) / torch.where(dd2 > 0, dd2, torch.ones_like(dd2))
    s = torch.where(dd2 > 0, s.clamp(0.0, 1.0), torch.zeros_like(s))
    cx, cy = d0x + s * ddx, d0y + s * ddy
    clearance = torch.sqrt(cx * cx + cy * cy) - robot[..., 4:5].unsqueeze(-1) - humans[..., 4].unsqueeze(1)
    return _reward_from_clearance(clearance, mask.unsqueeze(1).expand_as(clearance), robot_next, params)


def occupancy_map(
    humans: torch.Tensor,
    mask: torch.Tensor,
    cell_num: int = 4,
    cell_size: float = 1.0,
    om_channel_size: int = 3,
) -> torch.Tensor:
    """Per-human local occupancy maps (CrowdNav's ``build_occupancy_maps``), batched.

    Conventions followed (those of CrowdNav):
    - The map of human i has its x-axis along i's velocity, angle atan2(vy_i, vx_i) (a standing human,
      atan2(0, 0) = 0, uses the world x-axis). Another human j is at (x, y) = R(-angle)(p_j - p_i).
    - Cell indices: ix = floor(x / cell_size + cell_num / 2), iy likewise; only 0 ≤ ix, iy < cell_num
      counts, so the map covers [-cell_num/2, cell_num/2) · cell_size around the human. Flat cell index
      = cell_num * iy + ix.
    - Channels (om_channel_size = 3): [occupied (1 if any other human in the cell, else 0), mean vx, mean
      vy], where a velocity is the other human's own velocity expressed in i's frame (rotated by
      -angle; CrowdNav calls it "relative" but does not subtract i's velocity). Empty cells are 0.
      om_channel_size = 2 drops the occupied channel, 1 keeps only it.
    - Layout interleaves channels per cell: value index = om_channel_size * cell + channel.
    - Human i itself, padded humans (mask False) and the robot are excluded; maps of padded humans are 0.

    Args:
        humans: (B, N, 5) human states.
        mask: (B, N) bool, real humans.
        cell_num: cells per side.
        cell_size: cell side [m].
        om_channel_size: 1, 2 or 3 channels.

    Returns:
        (B, N, cell_num**2 * om_channel_size) in the dtype of ``humans``.
    """
    if om_channel_size not in (1, 2, 3):
        raise ValueError(f"om_channel_size must be 1, 2 or 3, got {om_channel_size}")
    b, n = humans.shape[:2]
    ang = torch.atan2(humans[..., 3], humans[..., 2])  # (B, N)
    c, s = torch.cos(ang)[..., None], torch.sin(ang)[..., None]  # (B, N, 1) for centre human i
    dx = humans[:, None, :, 0] - humans[:, :, None, 0]  # (B, i, j)
    dy = humans[:, None, :, 1] - humans[:, :, None, 1]
    x = dx * c + dy * s
    y = dy * c - dx * s
    ix = torch.floor(x / cell_size + cell_num / 2)
    iy = torch.floor(y / cell_size + cell_num / 2)
    eye = torch.eye(n, dtype=torch.bool, device=humans.device)
    valid = (ix >= 0) & (ix < cell_num) & (iy >= 0) & (iy < cell_num)
    valid = valid & mask[:, :, None] & mask[:, None, :] & ~eye
    cell = torch.where(valid, cell_num * iy + ix, torch.zeros_like(ix)).long()
    onehot = torch.zeros(b, n, n, cell_num * cell_num, dtype=humans.dtype, device=humans.device)
    onehot.scatter_(-1, cell.unsqueeze(-1), valid.to(humans.dtype).unsqueeze(-1))  # (B, i, j, C)
    count = onehot.sum(dim=2)  # (B, i, C)
    channels = []
    if om_channel_size in (1, 3):
        channels.append((count > 0).to(humans.dtype))
    if om_channel_size in (2, 3):
        vjx, vjy = humans[:, None, :, 2], humans[:, None, :, 3]  # (B, 1, j)
        vx = vjx * c + vjy * s  # (B, i, j) velocity of j in i's frame
        vy = vjy * c - vjx * s
        vx = torch.where(valid, vx, torch.zeros_like(vx))
        vy = torch.where(valid, vy, torch.zeros_like(vy))
        denom = count.clamp(min=1)
        channels.append(torch.einsum("bij,bijc->bic", vx, onehot) / denom)
        channels.append(torch.einsum("bij,bijc->bic", vy, onehot) / denom)
    return torch.stack(channels, dim=-1).reshape(b, n, cell_num * cell_num * om_channel_size)
