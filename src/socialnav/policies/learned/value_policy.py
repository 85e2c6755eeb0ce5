"""Value-based policy with one-step lookahead, batched over episodes and candidate actions.

For every episode b and candidate action a of CrowdSim's discrete set (81 actions):
    value(b, a) = r̂(s_b, a) + γ^(dt · v_pref_b) · V(s'_b(a))
where s'(a) is the propagated robot state with the predicted human states, r̂ CrowdSim's reward on
it, and V the value network. The argmax is taken (ε-greedy with an explicit generator while training).
This is the action selection of CADRL (Chen et al., ICRA 2017), LSTM-RL / GA3C-CADRL-style (Everett et
al., IROS 2018) and SARL / OM-SARL (Chen et al., ICRA 2019).

Information settings (how the humans' next states are predicted):
- ``constant_velocity`` (default): humans keep their current velocity.
- ``oracle``: the caller passes the simulator's exact next human states (computed once per step for
  all actions; the robot's candidate action cannot change them).
- ``learned``: a trained :class:`~socialnav.policies.learned.predictor.StatePredictor` (RGL's state
  predictor) predicts them from the current robot and human states.
All are shared by all candidate actions, so the humans' next states, the occupancy maps (OM-SARL) and
the human part of the geometry are computed once per episode, and every candidate action of every
episode goes through the network in ONE forward pass of B·81 joint states.

Obstacles (``obstacle_encoding``, :mod:`socialnav.sim.obstacle_points`): the nearest points of the
episode's obstacle outlines are appended after the human slots as standing agents, so the networks
read them like humans; the last ``static_slots`` slots of a state are such points. They do not move
under any information setting, and the lookahead's reward counts them for collisions only. A policy
without an encoding (every checkpoint trained on open floors) ignores obstacles and computes what it
always did; with one, an open floor gives K padded slots, which no network reads.

Reward rule of the lookahead: ``end`` (CrowdNav's and RGL's one-step estimate: clearances at the end
positions only) or ``swept`` (the world's rule: swept collision and discomfort over the step).

The module's neighbours: :mod:`~socialnav.policies.learned.lookahead_inputs` turns an observation
into the tensors read here (obstacle points appended), :mod:`~socialnav.policies.learned.lookahead_reward`
computes r̂; this module predicts the humans, builds the network's input, scores the candidate actions
(torch or the native scorer), plans and chooses.

Model-predictive planning (MP-RGL, Chen et al., "Relational Graph Learning for Crowd Navigation",
IROS 2020) with depth d and width w: the d-step value of a state is

    V_d(s) = V(s)/d + (d−1)/d · max_{b ∈ top_w(s)} [ r̂(s, b) + γ^(dt·v_pref) · V_{d−1}(s'(b)) ],  V_1 = V,

where top_w(s) are the w actions with the best one-step values at s and s'(b) uses the predicted
human states. At the root every action gets its one-step value; for d ≥ 2 the top w actions are
re-scored with r̂ + γ·V_d(s') and the others are excluded (value −inf). d = 1 is exactly the one-step
lookahead. Every level is batched over episodes and actions (B·w^level·K states per pass).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Literal

import numpy as np
import torch

from socialnav.policies.learned.actions import Kinematics, discrete_actions, num_actions
from socialnav.policies.learned.lookahead_inputs import (
    LookaheadInputs,
    encode_observation,
    encode_state_arrays,
    lookahead_inputs,
    network_composition,
    to_tensor,
)
from socialnav.policies.learned.lookahead_reward import REWARD_RULES, lookahead_reward
from socialnav.policies.learned.native_scoring import (
    SCORERS,
    NativeSarlScorer,
    ScorerError,
    native_unavailable_reason,
)
from socialnav.policies.learned.networks import ValueNetwork
from socialnav.policies.learned.state import (
    DiffDriveLimits,
    RewardParams,
    occupancy_map,
    propagate_humans_constant_velocity,
    propagate_robot,
    rotate,
)
from socialnav.policies.learned_catalog import VALUE_INFORMATION
from socialnav.sim.obstacle_points import ObstaclePoints
from socialnav.sim.parts.base import NETWORK_PARTS

__all__ = ["ValuePolicy", "Information"]

Information = Literal["constant_velocity", "oracle", "learned"]
INFORMATION: tuple[str, ...] = VALUE_INFORMATION


class ValuePolicy:
    """One-step-lookahead value policy around a value network.

    Args:
        network: a :class:`ValueNetwork` (CADRL, LSTMRL, SARL, OM-SARL).
        kinematics: "holonomic", "unicycle" or "diff_drive" (needs ``diff_drive``).
        gamma: discount per second of travel at v_pref (the lookahead uses γ^(dt·v_pref)).
        reward_params: reward constants for r̂.
        information: "constant_velocity", "oracle" or "learned" (needs ``predictor``).
        dt: time step [s], used when the observation carries none.
        rotation_limit, speed_samples, rotation_samples: the discrete action set.
        device: where the computation runs (default: the network's device).
        states_per_pass: the B·K joint states, built in one batched pass, go through the network in
            blocks of this many states so that activations stay in the CPU cache (results are
            identical; each block holds every action of many episodes). None: a single call.
        predictor: the trained state predictor (``information="learned"``).
        planning_depth, planning_width: d and w of model-predictive planning (1, 1: one-step).
        reward_rule: "end" (clearances at the end of the step) or "swept" (the world's rule).
        scorer: what evaluates the network on the lookahead's states: "torch" (the module itself,
            the default, and what training uses), "native" (the C++ SARL / OM-SARL evaluator of
            :mod:`~socialnav.policies.learned.native_scoring`, CPU only; values equal to float32
            rounding) or "auto" (native where it applies, torch otherwise; what ``socialnav
            evaluate`` uses). Gradients never flow through the native scorer: with autograd on, the
            module is used.
        obstacle_encoding: how the observation's obstacles reach the network
            (:class:`~socialnav.sim.obstacle_points.ObstaclePoints` or its dict); None: the network
            does not see obstacles (every checkpoint trained without walls).
        observation_parts: the named observation parts the network reads (its record's
            ``observation_parts``): the robot's state, then sets of agents read like humans
            (:func:`~socialnav.policies.learned.lookahead_inputs.network_composition`).
        diff_drive: a differential drive's limits (``DiffDriveSettings.to_dict()``): the lookahead
            reaches each command within them from the observation's ``robot_twist`` and drives the arc, as
            the world does; the network values the states reached (not their twist).
    """

    def __init__(
        self,
        network: ValueNetwork,
        kinematics: Kinematics = "holonomic",
        gamma: float = 0.9,
        reward_params: RewardParams | None = None,
        information: Information = "constant_velocity",
        dt: float = 0.25,
        rotation_limit: float = math.pi / 4,
        speed_samples: int = 5,
        rotation_samples: int = 16,
        device: torch.device | str | None = None,
        states_per_pass: int | None = 1024,
        predictor: torch.nn.Module | None = None,
        planning_depth: int = 1,
        planning_width: int = 1,
        reward_rule: str = "end",
        scorer: str = "torch",
        obstacle_encoding: ObstaclePoints | dict | None = None,
        observation_parts: Sequence[str] = NETWORK_PARTS,
        diff_drive: Mapping[str, Any] | None = None,
    ) -> None:
        if kinematics not in ("holonomic", "unicycle", "diff_drive"):
            raise ValueError(f"unknown kinematics {kinematics!r}; expected 'holonomic', 'unicycle' or "
                             "'diff_drive'")
        if kinematics == "diff_drive" and diff_drive is None:
            raise ValueError("a diff_drive value policy needs the robot's diff_drive limits: its lookahead "
                             "reaches each command within them (docs/kinematics.md)")
        #: The differential drive's limits the lookahead applies (None for the other kinematics).
        self.diff_drive_limits = (
            DiffDriveLimits.of(dict(diff_drive), rotation_limit) if kinematics == "diff_drive" and diff_drive
            else None
        )
        if information not in INFORMATION:
            raise ValueError(
                f"unknown information setting {information!r}; expected one of {', '.join(INFORMATION)}"
            )
        if information == "learned" and predictor is None:
            raise ValueError("information='learned' needs a trained state predictor (none was given)")
        if reward_rule not in REWARD_RULES:
            raise ValueError(
                f"unknown reward_rule {reward_rule!r}; expected one of {', '.join(REWARD_RULES)}"
            )
        if scorer not in SCORERS:
            raise ScorerError(f"unknown scorer {scorer!r}; expected one of {', '.join(SCORERS)}")
        if int(planning_depth) < 1 or int(planning_width) < 1:
            raise ValueError(
                f"planning_depth and planning_width must be >= 1, got {planning_depth} and {planning_width}"
            )
        if int(planning_depth) > 1 and information == "oracle":
            raise ValueError(f"information 'oracle' knows the humans' next step only, and the planning "
                             f"depth is {int(planning_depth)}: plan at depth 1 (--planning-depth 1 "
                             "--planning-width 1)")
        self.network = network
        self.obstacle_encoding = (
            None if obstacle_encoding is None else ObstaclePoints.from_dict(obstacle_encoding)
        )
        self.observation_parts = tuple(observation_parts)
        network_composition(self.obstacle_encoding, self.observation_parts)  # refuses parts it cannot read
        self.predictor = predictor
        self.planning_depth = int(planning_depth)
        self.planning_width = int(planning_width)
        self.reward_rule = reward_rule
        self.kinematics: Kinematics = kinematics
        self.gamma = float(gamma)
        self.reward_params = reward_params if reward_params is not None else RewardParams()
        self.information: Information = information
        self.dt = float(dt)
        self.rotation_limit = float(rotation_limit)
        self.speed_samples = int(speed_samples)
        self.rotation_samples = int(rotation_samples)
        self.states_per_pass = None if states_per_pass is None else max(1, int(states_per_pass))
        if device is None:
            p = next(network.parameters(), None)
            device = p.device if p is not None else torch.device("cpu")
        self.device = torch.device(device)
        self.network.to(self.device)
        if self.predictor is not None:
            self.predictor.to(self.device)
        self.scorer = scorer
        self._native: NativeSarlScorer | None = None
        if scorer != "torch":
            reason = native_unavailable_reason(network, self.device)
            if reason is None:
                self._native = NativeSarlScorer(network)
            elif scorer == "native":
                raise ScorerError(f"scorer 'native' is not available: {reason}")

    @property
    def active_scorer(self) -> str:
        """What evaluates the network: "native" or "torch" (``scorer="auto"`` resolved)."""
        return "native" if self._native is not None else "torch"

    @property
    def native_kernel(self) -> str | None:
        """The native scorer's vector kernel ("avx2" or "avx512"), None with the torch scorer."""
        return self._native.kernel if self._native is not None else None

    @property
    def num_actions(self) -> int:
        """The number K of candidate actions (speeds × rotations, plus stopping)."""
        return num_actions(self.speed_samples, self.rotation_samples)

    @property
    def model_dtype(self) -> torch.dtype:
        """The floating-point type of the network's parameters (float32 for a network without any)."""
        p = next(self.network.parameters(), None)
        return p.dtype if p is not None else torch.float32

    # ------------------------------------------------------------------ helpers
    def encode(self, obs: Any) -> Any:
        """``obs`` with the obstacle encoding's point slots appended, when this policy has an encoding.

        ``static_slots`` is set (all padded on an open floor); without an encoding ``obs`` itself is returned.
        An observation already encoded, or given as a mapping, is returned as it is
        (:func:`~socialnav.policies.learned.lookahead_inputs.encode_observation`).
        """
        return encode_observation(obs, self.obstacle_encoding, self.observation_parts)

    def encode_arrays(self, robot: np.ndarray, humans: np.ndarray, mask: np.ndarray,
                      maps: Any) -> tuple[np.ndarray, np.ndarray]:
        """Raw state arrays with the obstacle points of ``maps`` appended.

        Robot (B, 9), humans (B, N, 5) and mask (B, N); ``maps`` is (B,) StaticMap or None each (None: open
        floors); see :meth:`encode`. Unchanged when this policy has no encoding.
        """
        return encode_state_arrays(robot, humans, mask, maps, self.obstacle_encoding, self.observation_parts)

    def predict_humans(
        self,
        robot: torch.Tensor,
        humans: torch.Tensor,
        mask: torch.Tensor,
        dt: float,
        next_humans: torch.Tensor | None = None,
        static: int = 0,
    ) -> torch.Tensor:
        """Humans' predicted next states (B, N, 5) under the information setting.

        The last ``static`` slots (obstacle points) stay where they are.
        """
        if static and self.information != "oracle":
            moving = self.predict_humans(robot, humans[:, :-static], mask[:, :-static], dt)
            return torch.cat([moving, humans[:, -static:]], dim=1)
        if self.information == "oracle":
            if next_humans is None:
                raise ValueError("information='oracle' needs next_humans (B, N, 5) from the simulator")
            return next_humans
        if self.information == "learned":
            assert self.predictor is not None
            with torch.no_grad():
                return self.predictor(robot, humans, mask, dt)
        return propagate_humans_constant_velocity(humans, dt)

    def transform(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """Network input for states: (…, 9) robot, (B, N, 5) humans → (…, N, D).

        ``robot`` may carry extra leading dims after B (e.g. (B, K, 9) for K candidate actions); the
        human part (and the occupancy map for OM-SARL) is computed once per episode and broadcast.
        """
        extra = robot.dim() - 2
        h = humans.view(humans.shape[0], *([1] * extra), *humans.shape[1:])
        joint = rotate(robot, h, self.kinematics, dtype=self.model_dtype)
        if self.network.with_om:
            om = occupancy_map(humans, mask)
            om = om.view(om.shape[0], *([1] * extra), *om.shape[1:]).expand(*joint.shape[:-1], om.shape[-1])
            joint = torch.cat([joint, om.to(self.model_dtype)], dim=-1)
        return joint

    # ------------------------------------------------------------------ lookahead and planning
    def _step_values(
        self,
        robot: torch.Tensor,
        humans: torch.Tensor,
        mask: torch.Tensor,
        dt: float,
        nh: torch.Tensor | None,
        static: int = 0,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """One-step lookahead from B states.

        Returns q (B, K), actions (B, K, 2) [m/s], r (B, K), discount (B, 1), next robot states (B, K, 9) and
        predicted next human states (B, N, 5).
        """
        b, n = humans.shape[:2]
        k = self.num_actions
        actions = discrete_actions(
            self.kinematics, robot[:, 7], self.rotation_limit, self.speed_samples, self.rotation_samples
        )  # (B, K, 2)
        # (B, K, 9), or (B, K, 11) with a differential drive's (v, ω)
        robot_next = propagate_robot(robot, actions, self.kinematics, dt, self.diff_drive_limits)
        humans_next = self.predict_humans(robot, humans, mask, dt, nh, static)  # (B, N, 5)
        r = lookahead_reward(
            robot, robot_next, humans, humans_next, mask, static, self.reward_rule, self.reward_params
        )
        joint = self.transform(robot_next, humans_next, mask)  # (B, K, N, D)
        m = mask.unsqueeze(1).expand(b, k, n).reshape(b * k, n)
        v = self._network_values(joint.reshape(b * k, n, -1), m).view(b, k).to(r.dtype)
        disc = torch.pow(torch.as_tensor(self.gamma, dtype=r.dtype, device=r.device), dt * robot[:, 7:8])
        return r + disc * v, actions, r, disc, robot_next, humans_next

    def _state_value(self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        """V(s) of M states, (M,)."""
        joint = self.transform(robot, humans, mask)
        return self._network_values(joint, mask).to(robot.dtype)

    def _planned_value(
        self, robot: torch.Tensor, humans: torch.Tensor, mask: torch.Tensor, depth: int, dt: float,
        static: int = 0,
    ) -> torch.Tensor:
        """V_depth of M states (see the module docstring), (M,)."""
        v = self._state_value(robot, humans, mask)
        if depth == 1:
            return v
        q, _, r, disc, robot_next, humans_next = self._step_values(robot, humans, mask, dt, None, static)
        if depth == 2:  # V_1 = V: the best of the top w one-step values is the best one-step value
            best = q.amax(dim=1)
        else:
            top, returns = self._top_returns(
                q, r, disc, robot_next, humans_next, mask, depth - 1, dt, static
            )
            best = returns.amax(dim=1)
        return v / depth + (depth - 1) / depth * best

    def _top_returns(
        self,
        q: torch.Tensor,
        r: torch.Tensor,
        disc: torch.Tensor,
        robot_next: torch.Tensor,
        humans_next: torch.Tensor,
        mask: torch.Tensor,
        depth: int,
        dt: float,
        static: int = 0,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """The top-w actions of each of M states by one-step value q (M, K), and their returns.

        Returns are r̂ + γ·V_depth(s') (M, w); the w successors of every state are planned in one batched
        call.
        """
        m, w = q.shape[0], min(self.planning_width, q.shape[1])
        top = q.topk(w, dim=1).indices  # (M, w)
        rn = robot_next.gather(1, top.unsqueeze(-1).expand(m, w, robot_next.shape[-1]))
        deeper = self._planned_value(
            rn.reshape(m * w, -1),
            humans_next.repeat_interleave(w, dim=0),
            mask.repeat_interleave(w, dim=0),
            depth,
            dt,
            static,
        ).view(m, w)
        return top, r.gather(1, top) + disc * deeper

    @torch.inference_mode()
    def _values(
        self,
        robot: torch.Tensor,
        humans: torch.Tensor,
        mask: torch.Tensor,
        nh: torch.Tensor | None,
        dt: float,
        static: int = 0,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        q, actions, r, disc, robot_next, humans_next = self._step_values(robot, humans, mask, dt, nh, static)
        d = self.planning_depth
        if d == 1:
            return q, actions
        top, returns = self._top_returns(q, r, disc, robot_next, humans_next, mask, d, dt, static)
        planned = torch.full_like(q, float("-inf"))
        planned.scatter_(1, top, returns)
        return planned, actions

    def _network_values(self, joint: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
        native = self._native
        if native is not None and not (
            torch.is_grad_enabled() and any(p.requires_grad for p in self.network.parameters())
        ):
            reason = native.unavailable_reason()  # the network may have moved since (device, dtype)
            if reason is None:
                return native.value(joint, mask).to(self.device)
            if self.scorer == "native":
                raise ScorerError(f"scorer 'native' is not available: {reason}")
        total, c = joint.shape[0], self.states_per_pass
        if c is None or total <= c or self.device.type != "cpu":
            return self.network.value(joint, mask)
        return torch.cat([self.network.value(joint[s : s + c], mask[s : s + c]) for s in range(0, total, c)])

    def _lookahead_inputs(self, obs: Any, next_humans: Any) -> LookaheadInputs:
        """The observation as tensors; a differential drive's rows with its (v, ω) appended.

        Raises:
            ValueError: A differential drive's observation without ``robot_twist``.
        """
        inputs = lookahead_inputs(self.encode(obs), next_humans, self.device, self.dt)
        if self.diff_drive_limits is None:
            return inputs
        twist = obs.get("robot_twist") if isinstance(obs, Mapping) else getattr(obs, "robot_twist", None)
        if twist is None:
            raise ValueError("a diff_drive value policy needs the observation's robot_twist, the (v, ω) its "
                             "acceleration limits act from (docs/kinematics.md)")
        robot = torch.cat([inputs.robot, to_tensor(twist, self.device, inputs.robot.dtype)], -1)
        return inputs._replace(robot=robot)

    # ------------------------------------------------------------------ public API
    def values(self, obs: Any, next_humans: Any = None) -> np.ndarray | torch.Tensor:
        """Lookahead values of every discrete action.

        Args:
            obs: Observation-like (attributes or keys ``robot`` (B, 9), ``humans`` (B, N, 5),
                ``human_mask`` (B, N), optional ``dt``), NumPy or torch.
            next_humans: (B, N, 5) exact next human states (``oracle`` only).

        Returns:
            (B, K) values, NumPy if the observation was NumPy.
        """
        robot, humans, mask, nh, dt, as_numpy, static = self._lookahead_inputs(obs, next_humans)
        q, _ = self._values(robot, humans, mask, nh, dt, static)
        return q.cpu().numpy() if as_numpy else q

    def act(
        self,
        obs: Any,
        epsilon: float = 0.0,
        generator: torch.Generator | None = None,
        next_humans: Any = None,
    ) -> tuple[np.ndarray | torch.Tensor, np.ndarray | torch.Tensor]:
        """Choose one action per episode: argmax of the lookahead values, ε-greedy if ε > 0.

        Args:
            obs: see :meth:`values`.
            epsilon: probability of a uniformly random action, per episode.
            generator: torch.Generator on CPU drawing the exploration (required when ε > 0).
            next_humans: (B, N, 5) exact next human states, computed once per step (``oracle``).

        Returns:
            action_index (B,) int64 and action (B, 2) (holonomic (vx, vy) or unicycle (v, dθ)),
            NumPy if the observation was NumPy.
        """
        robot, humans, mask, nh, dt, as_numpy, static = self._lookahead_inputs(obs, next_humans)
        b = robot.shape[0]
        if epsilon >= 1.0:  # no need to score anything
            actions = discrete_actions(
                self.kinematics, robot[:, 7], self.rotation_limit, self.speed_samples, self.rotation_samples
            )
            q = None
        else:
            q, actions = self._values(robot, humans, mask, nh, dt, static)
        if epsilon > 0.0:
            if generator is None:
                raise ValueError("epsilon > 0 needs an explicit torch.Generator (no hidden global RNG)")
            explore = torch.rand(b, generator=generator, device=generator.device) < epsilon
            rand_idx = torch.randint(0, self.num_actions, (b,), generator=generator, device=generator.device)
            explore, rand_idx = explore.to(self.device), rand_idx.to(self.device)
            idx = rand_idx if q is None else torch.where(explore, rand_idx, q.argmax(dim=1))
        else:
            assert q is not None
            idx = q.argmax(dim=1)
        act = actions[torch.arange(b, device=self.device), idx]
        if as_numpy:
            return idx.cpu().numpy(), act.cpu().numpy()
        return idx, act
