"""The attention-graph actor-critic of CrowdNav++ (policy-gradient, continuous actions, recurrent).

Reference: S. Liu, P. Chang, Z. Huang, N. Chakraborty, K. Hong, W. Liang, D. L. McPherson, J. Geng,
K. Driggs-Campbell, "Intention Aware Robot Crowd Navigation with Attention-Based Interaction Graph",
ICRA 2023. Implemented from the paper's description; the layer sizes are the defaults of the authors'
public repository (Shuijing725/CrowdNav_Prediction_AttnGraph, ``arguments.py`` and
``rl/networks/selfAttn_srnn_temp_node.py``), read for reference, no code copied:

    robot node   r   = ReLU(W_r [robot features (9)])                         9 → 256
    human nodes  e_i = MLP([relative position now and K predicted, 2(1+K)])   2(1+K) → 128 → 512
    human-human  z_i = multi-head self-attention over the real humans          512, 8 heads
                 u_i = ReLU(W_u z_i)                                           512 → 256
    robot-human  a   = Σ_i softmax_i((Q r)·(K u_i) / √d) u_i                   d = 64; masked softmax
    temporal     h_t = GRU([ReLU(W_1 r), ReLU(W_2 a)], h_{t-1})                64 + 64 → 128
                 o_t = W_o h_t                                                 128 → 256
    actor        μ   = W_μ tanh-MLP(o_t), σ = exp(log σ) (state-independent)   256 → 256 → 256 → 2
    critic       V   = W_v tanh-MLP(o_t)                                       256 → 256 → 256 → 1

Two decisions differ from the repository and are documented in docs/ppo.md: the robot-human scores
use the standard 1/√d scaling (the repository multiplies by N/√d, which grows with the number of
humans), and padded human slots are masked by the observation's mask (the repository sorts humans
and masks by a count; the two are the same set). With no real human the attention output is the
zero vector, so the policy acts on the robot's own state.

Prediction: the paper feeds the GST predictor's 5 future positions of each human; here they are the
constant-velocity extrapolation p_i + k·dt·v_i, k = 1..K (K = ``prediction_steps``, 5 by default;
0 turns prediction off), which is the repository's own "constant velocity" variant
(``CrowdSimPred-v0``); see docs/ppo.md for why GST is not used.

Obstacles (a network trained among walls): :func:`observation_tensors` appends the K nearest
outline points of the episode's map after the human slots as standing agents with their own mask
(:mod:`socialnav.sim.obstacle_points`, docs/walls_learned.md). The network reads them as humans that
never move: they take part in both attentions and need no new layer. With all K slots masked (an
open floor) the network computes what it computes without them, up to float32 rounding (the sums
run over more, zero, terms).

Observation normalisation (optional, ``normalize_obs``): running mean and variance of the robot
features and of the real humans' features, kept as buffers so that they travel with the checkpoint;
the trainer updates them after each update with that rollout's observations (:meth:`update_obs_stats`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch
from torch import nn

from socialnav.policies.learned.lookahead_inputs import encode_observation
from socialnav.sim.parts.base import NETWORK_PARTS
from socialnav.sim.settings import KINEMATICS

__all__ = [
    "AttnGraphNet",
    "ObservationStatistics",
    "ROBOT_FEATURES",
    "robot_features",
    "human_features",
    "observation_tensors",
]

#: Robot features: goal offset (2), distance to goal, velocity (2), radius, v_pref, cos θ, sin θ.
ROBOT_FEATURES = 9
#: Normalised features are clipped to ±this many standard deviations (as CleanRL's wrappers do).
OBS_CLIP = 10.0


def robot_features(robot: torch.Tensor) -> torch.Tensor:
    """(…, 9) robot features from the observation's (…, 9) robot rows (world frame, translation-free)."""
    d = robot[..., 5:7] - robot[..., 0:2]
    dist = torch.linalg.vector_norm(d, dim=-1, keepdim=True)
    theta = robot[..., 8:9]
    return torch.cat(
        [d, dist, robot[..., 2:4], robot[..., 4:5], robot[..., 7:8], theta.cos(), theta.sin()], -1
    )


def human_features(
    robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor, dt: float, steps: int
) -> torch.Tensor:
    """Each human's position relative to the robot, now and extrapolated: (…, N, 2(1+steps)).

    The next ``steps`` steps use constant-velocity extrapolation; padded slots are zero.
    """
    rel = humans[..., 0:2] - robot[..., None, 0:2]
    k = torch.arange(steps + 1, dtype=humans.dtype, device=humans.device) * dt  # 0, dt, …, K·dt
    pred = rel[..., None, :] + k[:, None] * humans[..., None, 2:4]  # (…, N, K+1, 2)
    out = pred.flatten(-2)
    return out * mask[..., None].to(out.dtype)


def observation_tensors(
    obs, dt: float, steps: int, device: torch.device | str = "cpu", obstacle_encoding: Any = None,
    parts: Sequence[str] = NETWORK_PARTS,
):
    """(robot features, human features, mask) float32 tensors of an Observation.

    With an ``obstacle_encoding`` (:class:`~socialnav.sim.obstacle_points.ObstaclePoints`), its K
    slots follow the human slots: the nearest outline points of each episode's map as standing
    agents (zero velocity, so their predicted positions stay where they are), nearest first, masked
    where padded (all of them on an open floor). An observation whose ``static_slots`` says it
    already holds the points is taken as it is.

    Args:
        obs: an :class:`~socialnav.sim.observation.Observation` of B episodes.
        dt: the step length [s] of the predicted positions.
        steps: predicted steps per human.
        device: where the tensors go.
        obstacle_encoding: the encoding of the obstacles, or None (the network reads none).
        parts: the network's observation parts (its record's ``observation_parts``): the robot's state,
            then the sets of agents it reads as humans, in order.

    Returns:
        Robot features (B, 9), human features (B, N [+ K], 2(1 + steps)) and the mask (B, N [+ K]).
    """
    obs = encode_observation(obs, obstacle_encoding, parts)
    robot = torch.as_tensor(obs.robot, dtype=torch.float64)
    humans = torch.as_tensor(obs.humans, dtype=torch.float64)
    mask = torch.as_tensor(obs.human_mask, dtype=torch.bool)
    rf = robot_features(robot).float().to(device)
    hf = human_features(robot, humans, mask, dt, steps).float().to(device)
    return rf, hf, mask.to(device)


def _init(layer: nn.Linear, gain: float = math.sqrt(2.0)) -> nn.Linear:
    nn.init.orthogonal_(layer.weight, gain)
    nn.init.zeros_(layer.bias)
    return layer


class _SelfAttention(nn.Module):
    """Multi-head scaled dot-product self-attention over the real humans (Vaswani et al. 2017).

    Padded slots are neither attended to nor (their outputs are zeroed) attending.
    """

    def __init__(self, size: int, heads: int) -> None:
        super().__init__()
        if size % heads:
            raise ValueError(f"attn_size {size} must be a multiple of attn_heads {heads}")
        self.heads = heads
        self.q, self.k, self.v, self.out = (nn.Linear(size, size) for _ in range(4))

    def forward(self, x: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        b, n, s = x.shape
        h, d = self.heads, s // self.heads

        def split(t: torch.Tensor) -> torch.Tensor:
            return t.view(b, n, h, d).transpose(1, 2)  # (b, h, n, d)

        q, k, v = split(self.q(x)), split(self.k(x)), split(self.v(x))
        scores = q @ k.transpose(-1, -2) / math.sqrt(d)  # (b, h, n, n)
        keep = mask[:, None, None, :]
        # A row without any real human would be all -inf (NaN softmax): it gets zero weights instead.
        scores = scores.masked_fill(~keep, float("-inf"))
        w = torch.softmax(scores.masked_fill(~mask.any(-1)[:, None, None, None], 0.0), dim=-1)
        w = w * keep
        z = (w @ v).transpose(1, 2).reshape(b, n, s)
        return self.out(z) * mask[..., None]


class ObservationStatistics(nn.Module):
    """Running mean and variance of the robot's and the real humans' features.

    Float64 buffers (they travel with the checkpoint), and the normalisation they define.
    """

    input_dim: int
    normalize_obs: bool
    #: Width of the robot features normalised here (the robot's features, and its twist where read).
    robot_state_width: int = ROBOT_FEATURES

    def _init_obs_stats(self) -> None:
        w = self.robot_state_width
        self.register_buffer("obs_count", torch.zeros((), dtype=torch.float64))
        self.register_buffer("robot_mean", torch.zeros(w, dtype=torch.float64))
        self.register_buffer("robot_var", torch.ones(w, dtype=torch.float64))
        self.register_buffer("human_count", torch.zeros((), dtype=torch.float64))
        self.register_buffer("human_mean", torch.zeros(self.input_dim, dtype=torch.float64))
        self.register_buffer("human_var", torch.ones(self.input_dim, dtype=torch.float64))

    @torch.no_grad()
    def update_obs_stats(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> None:
        """Fold a batch into the running mean/variance (Chan et al.'s parallel update).

        Padded human slots are left out.
        """
        _fold(self.obs_count, self.robot_mean, self.robot_var, robot.reshape(-1, self.robot_state_width))
        _fold(self.human_count, self.human_mean, self.human_var, humans[mask])

    def _normalized(self, robot: torch.Tensor, humans: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        if not self.normalize_obs:
            return robot, humans

        def norm(x, mean, var):
            return ((x - mean.to(x.dtype)) / torch.sqrt(var.to(x.dtype) + 1e-8)).clamp(-OBS_CLIP, OBS_CLIP)

        return norm(robot, self.robot_mean, self.robot_var), norm(humans, self.human_mean, self.human_var)


class AttnGraphNet(ObservationStatistics):
    """CrowdNav++'s attention-graph actor-critic (module docstring); sizes default to the repository's.

    ``input_dim`` is the per-human feature size, 2(1 + prediction_steps). With ``twist_features`` (a
    differential-drive robot, whose acceleration limits act from the (v, ω) it last drove) the robot's
    features are followed by that twist (``Observation.robot_twist``; ppo_inputs.network_inputs).
    """

    def __init__(
        self,
        prediction_steps: int = 5,
        robot_embed: int = 256,
        human_hidden: int = 128,
        attn_size: int = 512,
        attn_heads: int = 8,
        human_out: int = 256,
        rh_attention: int = 64,
        gru_input: int = 64,
        gru_hidden: int = 128,
        node_out: int = 256,
        head_hidden: int = 256,
        self_attention: bool = True,
        normalize_obs: bool = True,
        log_std_init: float = 0.0,
        twist_features: bool = False,
    ) -> None:
        super().__init__()
        if prediction_steps < 0:
            raise ValueError(f"prediction_steps must be >= 0, got {prediction_steps}")
        self._kwargs = dict(
            prediction_steps=prediction_steps,
            robot_embed=robot_embed,
            human_hidden=human_hidden,
            attn_size=attn_size,
            attn_heads=attn_heads,
            human_out=human_out,
            rh_attention=rh_attention,
            gru_input=gru_input,
            gru_hidden=gru_hidden,
            node_out=node_out,
            head_hidden=head_hidden,
            self_attention=self_attention,
            normalize_obs=normalize_obs,
            log_std_init=log_std_init,
        )
        if twist_features:  # recorded only when set: the holonomic checkpoints' records stay as they are
            self._kwargs["twist_features"] = True
        self.twist_features = bool(twist_features)
        self.robot_state_width = ROBOT_FEATURES + (2 if twist_features else 0)
        self.prediction_steps = prediction_steps
        self.input_dim = 2 * (1 + prediction_steps)
        self.gru_hidden = gru_hidden
        self.normalize_obs = normalize_obs
        self.robot_embed = nn.Sequential(_init(nn.Linear(self.robot_state_width, robot_embed)), nn.ReLU())
        if self_attention:
            self.human_embed = nn.Sequential(
                _init(nn.Linear(self.input_dim, human_hidden)),
                nn.ReLU(),
                _init(nn.Linear(human_hidden, attn_size)),
                nn.ReLU(),
            )
            self.human_attention: _SelfAttention | None = _SelfAttention(attn_size, attn_heads)
            self.human_out = nn.Sequential(_init(nn.Linear(attn_size, human_out)), nn.ReLU())
        else:  # the paper's ablation without human-human attention
            self.human_embed = nn.Sequential(_init(nn.Linear(self.input_dim, human_hidden)), nn.ReLU())
            self.human_attention = None
            self.human_out = nn.Sequential(_init(nn.Linear(human_hidden, human_out)), nn.ReLU())
        self.rh_query = nn.Linear(robot_embed, rh_attention)
        self.rh_key = nn.Linear(human_out, rh_attention)
        self.gru_robot = nn.Sequential(nn.Linear(robot_embed, gru_input), nn.ReLU())
        self.gru_edges = nn.Sequential(nn.Linear(human_out, gru_input), nn.ReLU())
        self.gru = nn.GRUCell(2 * gru_input, gru_hidden)
        self.node_out = nn.Linear(gru_hidden, node_out)
        self.actor = nn.Sequential(
            _init(nn.Linear(node_out, head_hidden)),
            nn.Tanh(),
            _init(nn.Linear(head_hidden, head_hidden)),
            nn.Tanh(),
        )
        self.critic = nn.Sequential(
            _init(nn.Linear(node_out, head_hidden)),
            nn.Tanh(),
            _init(nn.Linear(head_hidden, head_hidden)),
            nn.Tanh(),
        )
        self.mean = _init(nn.Linear(head_hidden, 2), 0.01)  # near-zero initial actions (CleanRL)
        self.value_head = _init(nn.Linear(head_hidden, 1), 1.0)
        self.log_std = nn.Parameter(torch.full((2,), float(log_std_init)))
        self._init_obs_stats()

    def model_kwargs(self) -> dict:
        """The constructor's keyword arguments, saved with the checkpoint to rebuild the network."""
        return dict(self._kwargs)

    # -- forward passes --------------------------------------------------------------------------
    def encode(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """The GRU's input (M, 2·gru_input) for M states: robot (M, 9), humans (M, N, F), mask (M, N)."""
        robot, humans = self._normalized(robot, humans)
        r = self.robot_embed(robot)
        e = self.human_embed(humans)
        if self.human_attention is not None:
            e = self.human_attention(e, mask)
        u = self.human_out(e)  # (M, N, human_out)
        q = self.rh_query(r)
        k = self.rh_key(u)
        scores = (k @ q[..., None]).squeeze(-1) / math.sqrt(q.shape[-1])  # (M, N)
        scores = scores.masked_fill(~mask, float("-inf"))
        w = torch.softmax(scores.masked_fill(~mask.any(-1, keepdim=True), 0.0), dim=-1) * mask
        a = (w[..., None] * u).sum(-2)
        return torch.cat([self.gru_robot(r), self.gru_edges(a)], -1)

    def heads(self, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Action mean (…, 2) and value (…) from GRU states."""
        o = self.node_out(h)
        return self.mean(self.actor(o)), self.value_head(self.critic(o)).squeeze(-1)

    def initial_state(self, batch: int, device: torch.device | str = "cpu") -> torch.Tensor:
        """The GRU's initial hidden state: (batch, H) zeros on ``device``."""
        return torch.zeros(batch, self.gru_hidden, device=device)

    def step(self, robot, humans, mask, h, start) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """One time step for B episodes: ``h`` is zeroed where ``start`` (a new episode begins).

        Returns (action mean (B, 2), value (B,), new h (B, H)).
        """
        h = h * (~start)[:, None].to(h.dtype)
        h = self.gru(self.encode(robot, humans, mask), h)
        mean, value = self.heads(h)
        return mean, value, h

    def sequence(self, robot, humans, mask, h0, starts) -> tuple[torch.Tensor, torch.Tensor]:
        """Run T steps of B episodes at once (training).

        Inputs: robot (T, B, 9), humans (T, B, N, F), mask (T, B, N), h0 (B, H), starts (T, B). The attention
        is batched over all T·B states; the GRU runs T steps.

        Returns action means (T, B, 2) and values (T, B).
        """
        t, b = robot.shape[:2]
        x = self.encode(
            robot.reshape(t * b, -1), humans.reshape(t * b, *humans.shape[2:]), mask.reshape(t * b, -1)
        ).view(t, b, -1)
        keep = (~starts)[..., None].to(h0.dtype)
        h, hs = h0, []
        for i in range(t):
            h = self.gru(x[i], h * keep[i])
            hs.append(h)
        return self.heads(torch.stack(hs))


def _fold(count: torch.Tensor, mean: torch.Tensor, var: torch.Tensor, x: torch.Tensor) -> None:
    n = x.shape[0]
    if n == 0:
        return
    x = x.to(torch.float64)
    b_mean, b_var = x.mean(0), x.var(0, unbiased=False)
    total = count + n
    delta = b_mean - mean
    m2 = var * count + b_var * n + delta.square() * count * n / total
    mean.add_(delta * n / total)
    var.copy_(m2 / total)
    count.copy_(total)


#: How a Gaussian sample becomes a world action: ``radial`` (holonomic: onto the disc of radius v_pref),
#: ``span`` (unicycle and differential drive: [-1, 1] spans the commands) and ``clip`` (the unicycle's
#: until records named their squash: v clipped to [0, v_pref]; kept to load the checkpoints that name none).
ACTION_SQUASHES = ("radial", "span", "clip")


def trained_action_squash(kinematics: str) -> str:
    """The squash PPO trains a robot of ``kinematics`` with (recorded as ``ppo_policy.action_squash``)."""
    return "radial" if kinematics == "holonomic" else "span"


def recorded_action_squash(kinematics: str, record: Mapping[str, Any]) -> str:
    """The squash a checkpoint's ``ppo_policy`` record was trained with.

    A unicycle record without ``action_squash`` was written before the unicycle spanned its commands, so
    its actor clipped (docs/kinematics.md, "PPO on a unicycle and a differential drive").

    Raises:
        ValueError: an ``action_squash`` that is not one of :data:`ACTION_SQUASHES`, or not the
            kinematics' own.
    """
    squash = record.get("action_squash")
    if squash is None:
        return "clip" if kinematics == "unicycle" else trained_action_squash(kinematics)
    allowed = ("span", "clip") if kinematics == "unicycle" else (trained_action_squash(kinematics),)
    if squash not in allowed:
        raise ValueError(f"action_squash {squash!r} is not one for a {kinematics} robot (one of {allowed})")
    return str(squash)


def squash_actions(raw: np.ndarray, kinematics: str, v_pref: np.ndarray, rotation_limit: float,
                   max_reverse_speed: float = 0.0, squash: str | None = None) -> np.ndarray:
    """The world action of a raw Gaussian sample (the log-probability is that of ``raw``).

    Holonomic (v_x, v_y), ``radial``: scaled radially onto the disc of radius v_pref where it leaves it
    (the direction kept). Unicycle and differential drive (v, dθ), ``span``: the sample, clipped to
    [-1, 1], spans the commands the robot accepts: v from -max_reverse_speed (-1; 0 for a unicycle) to
    v_pref (1), dθ from -rotation_limit to rotation_limit (a differential drive's world then reaches them
    within its acceleration limits). The untrained network's zero mean is then half speed straight
    ahead, and no share of the samples is a command the world cuts off (with the run's initial σ e⁻¹;
    docs/kinematics.md says what else was tried). The unicycle's older ``clip``: v clipped to
    [0, v_pref], dθ to [-rotation_limit, rotation_limit].

    Args:
        raw: (B, 2) Gaussian samples (or means).
        kinematics: the robot's kinematics.
        v_pref: (B,) the robots' preferred speeds [m/s].
        rotation_limit: the largest heading change per step [rad].
        max_reverse_speed: a differential drive's reverse speed [m/s] (0 for a unicycle).
        squash: one of :data:`ACTION_SQUASHES`; None for :func:`trained_action_squash`.
    """
    raw = np.asarray(raw, dtype=np.float64)
    v_pref = np.asarray(v_pref, dtype=np.float64)
    if kinematics not in KINEMATICS:
        raise ValueError(f"kinematics must be 'holonomic', 'unicycle' or 'diff_drive', got {kinematics!r}")
    squash = trained_action_squash(kinematics) if squash is None else squash
    if squash == "radial":
        speed = np.hypot(raw[:, 0], raw[:, 1])
        scale = np.where(speed > v_pref, v_pref / np.maximum(speed, 1e-300), 1.0)
        return raw * scale[:, None]
    if squash == "clip":
        return np.stack(
            [np.clip(raw[:, 0], 0.0, v_pref), np.clip(raw[:, 1], -rotation_limit, rotation_limit)], 1
        )
    if squash == "span":
        u = np.clip(raw, -1.0, 1.0)
        v = -max_reverse_speed + (u[:, 0] + 1.0) * 0.5 * (v_pref + max_reverse_speed)
        return np.stack([v, u[:, 1] * rotation_limit], 1)
    raise ValueError(f"squash must be one of {ACTION_SQUASHES}, got {squash!r}")
