"""The batched World: B episode slots advanced by one native call per step.

Episodes come from an :class:`EpisodeStream` (scenario, split, index range). A finished episode is
recorded as a :class:`~socialnav.trajectory.Trajectory` and its slot is refilled in place from the
stream (auto-reset), so the batch never shrinks until the stream runs dry; then slots go idle.
Because every episode's initial state depends only on its (scenario, split, index) and episodes never
interact, an episode's trajectory is the same whatever the batch size or slot it ran in.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from socialnav import _core
from socialnav.scenarios import EpisodeBatch, Scenario, episode_seeds
from socialnav.scenarios.native import native_config, raise_on_failure
from socialnav.sim.observation import HUMAN_DIM, ROBOT_DIM, Observation, ObstacleArrays, build_observation
from socialnav.sim.pool import shared_pool
from socialnav.sim.recorder import COLLISION_KIND_NAMES, OUTCOME_NAMES, Recorder
from socialnav.sim.settings import WorldSettings
from socialnav.static_map import StaticMap

#: Memory one World may allocate for its state and recorded histories (docs/simulator.md, "Bounds").
MAX_WORLD_BYTES = 4 * 2**30
#: Native bytes per obstacle vertex and slot, for the memory check: the worst case, a different map in
#: every slot (slots with equal maps share one prepared copy).
OBSTACLE_VERTEX_BYTES = 128


def world_bytes(settings: WorldSettings, batch_size: int, n_agents: int, record: bool = True) -> int:
    """Bytes a World of ``batch_size`` slots of ``n_agents`` agents allocates (state + histories)."""
    T = settings.history_length() if record else 0
    return int(batch_size) * (int(n_agents) * (8 * 8 + 8 + 1) + 64 + int(T) * (int(n_agents) * 32 + 8))


def check_world_size(settings: WorldSettings, batch_size: int, n_agents: int, record: bool = True) -> None:
    """Raises a ValueError before allocating a World larger than :data:`MAX_WORLD_BYTES`."""
    need = world_bytes(settings, batch_size, n_agents, record)
    if need > MAX_WORLD_BYTES:
        raise ValueError(
            f"a world of {batch_size} episodes x {n_agents} agents x {settings.history_length()} steps "
            f"needs {need / 2**30:.1f} GiB, more than the {MAX_WORLD_BYTES / 2**30:.0f} GiB allowed "
            "(lower the batch size, the number of humans, or time_limit / dt)"
        )


_HUMAN_MODEL_IDS = {
    "orca": _core.HUMAN_ORCA,
    "social_force": _core.HUMAN_SOCIAL_FORCE,
    "linear": _core.HUMAN_LINEAR,
}


class EpisodeStream:
    """Hands out episodes (scenario, split, index) in index order: ``start, start+1, …``.

    Args:
        scenario: The scenario generator.
        split: "train", "val" or "test" (decides the seeds).
        start: First episode index (first position when ``index_map`` is given).
        count: Number of episodes, or None for an endless stream (training).
        index_map: Maps stream positions (int64 array) to episode indices, for streams that are
            not ``start, start+1, …`` (the Gymnasium envs' seeded and cycling orders). The map
            decides where such a stream ends: a finite scenario does not cap it.
    """

    #: Episodes generated per call: generation has a fixed cost per call, and a world refills only
    #: a few slots per step, so episodes are generated ahead in chunks (results do not change:
    #: each episode depends only on its own index).
    chunk_size = 1024

    def __init__(
        self,
        scenario: Scenario,
        split: str = "test",
        start: int = 0,
        count: int | None = None,
        index_map: Callable[[np.ndarray], np.ndarray] | None = None,
    ):
        if count is not None and count < 0:
            raise ValueError(f"count must be >= 0, got {count}")
        episode_seeds(split, np.zeros(1, dtype=np.int64))  # validates the split name early
        self.scenario = scenario
        self.split = split
        self.next_index = start  # next index handed out
        self._generated = start  # next index to generate
        self.stop = None if count is None else start + count
        self.index_map = index_map
        if scenario.n_episodes is not None and index_map is None:
            # A finite scenario (the single-human sweeps) ends the stream at its last episode.
            self.stop = scenario.n_episodes if self.stop is None else min(self.stop, scenario.n_episodes)
        self._buffer: EpisodeBatch | None = None
        self._buffer_pos = 0

    @property
    def remaining(self) -> int | None:
        return None if self.stop is None else self.stop - self.next_index

    @property
    def buffered(self) -> int:
        """Episodes generated ahead by :meth:`take` and not handed out yet."""
        return 0 if self._buffer is None else len(self._buffer) - self._buffer_pos

    def take_indices(self, k: int) -> np.ndarray | None:
        """The indices of the next ``min(k, remaining)`` episodes, without generating them (a world
        with a native generator generates them in place), or None when exhausted.

        Raises:
            RuntimeError: :meth:`take` generated episodes ahead that were not handed out yet.
        """
        if self.buffered:
            raise RuntimeError("take_indices after take: hand out the buffered episodes with take first")
        if self.stop is not None:
            k = min(k, self.stop - self.next_index)
        if k <= 0:
            return None
        indices = np.arange(self.next_index, self.next_index + k, dtype=np.int64)
        if self.index_map is not None:
            indices = np.asarray(self.index_map(indices), dtype=np.int64)
        self.next_index += k
        self._generated = self.next_index
        return indices

    def take(self, k: int) -> EpisodeBatch | None:
        """The next ``min(k, remaining)`` episodes, or None when exhausted."""
        if self.stop is not None:
            k = min(k, self.stop - self.next_index)
        if k <= 0:
            return None
        buffered = 0 if self._buffer is None else len(self._buffer) - self._buffer_pos
        if buffered < k:
            n = max(k - buffered, self.chunk_size)
            if self.stop is not None:
                n = min(n, self.stop - self._generated)
            indices = np.arange(self._generated, self._generated + n, dtype=np.int64)
            if self.index_map is not None:
                indices = np.asarray(self.index_map(indices), dtype=np.int64)
            fresh = self.scenario.generate(indices, episode_seeds(self.split, indices))
            self._generated += n
            parts = [fresh] if buffered == 0 else [self._buffer.take(slice(self._buffer_pos, None)), fresh]
            self._buffer = parts[0] if len(parts) == 1 else EpisodeBatch.concat(parts)
            self._buffer_pos = 0
        out = self._buffer.take(slice(self._buffer_pos, self._buffer_pos + k))
        self._buffer_pos += k
        self.next_index += k
        return out


@dataclass(frozen=True)
class StepResult:
    """What one batched step returns (arrays over the B slots).

    Attributes:
        reward: (B,) reward of the step (0 for idle slots).
        terminated: (B,) episode ended by success or collision in this step.
        truncated: (B,) episode ended by the time limit in this step.
        finished: trajectories of the episodes that ended in this step (empty when not recording).
        final_observation: observation of the finished slots before their reset (rows where done).
        outcome: (B,) "success", "collision" or "timeout" where an episode ended in this step, "" elsewhere.
        final_dmin: (B,) the finished episodes' minimum robot-human distance (NaN elsewhere).
        final_episode: (B,) the finished episodes' indices (-1 elsewhere).
        outcome_code: (B,) int8 final status code where an episode ended (``_core.STATUS_*``; 0,
            running, elsewhere); ``outcome`` names it.
        observation: the observation after the step (``World.step(..., observe=True)`` only).
        collision_kind_code: (B,) int8 ``_core.COLLISION_*`` where an episode ended in a collision
            (1 human, 2 obstacle), 0 elsewhere; ``collision_kind`` names it.
    """

    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    finished: list
    final_observation: Observation | None
    outcome_code: np.ndarray
    final_dmin: np.ndarray | None = None
    final_episode: np.ndarray | None = None
    observation: Observation | None = None
    collision_kind_code: np.ndarray | None = None

    @property
    def collision_kind(self) -> np.ndarray:
        """(B,) "human" or "obstacle" where an episode ended in a collision, "" elsewhere."""
        if self.collision_kind_code is None:
            return np.full(len(self.reward), "", dtype=object)
        return _COLLISION_KIND_BY_CODE[self.collision_kind_code]

    @property
    def outcome(self) -> np.ndarray:
        """(B,) "success", "collision" or "timeout" where an episode ended in this step, "" elsewhere
        (built on access: most steps' callers only read the numeric fields)."""
        return _OUTCOME_BY_STATUS[self.outcome_code]


#: Outcome name by final status code (an object array: one fancy-index per step, no Python loop).
_OUTCOME_BY_STATUS = np.array(
    [OUTCOME_NAMES.get(code, "") for code in range(max(OUTCOME_NAMES) + 1)], dtype=object
)
_COLLISION_KIND_BY_CODE = np.array(
    [COLLISION_KIND_NAMES.get(code, "") for code in range(max(COLLISION_KIND_NAMES) + 1)], dtype=object
)


class World:
    """B episode slots of (1 robot + N humans) stepped in lockstep by the native core.

    Args:
        settings: Simulator semantics.
        scenario: Where episodes come from.
        batch_size: Number of slots B.
        split: "train", "val" or "test": the episode stream's split (see :class:`EpisodeStream`).
        start: First episode index of the stream.
        count: Number of episodes, or None for an endless stream (training).
        record: Keep per-episode histories and emit trajectories when episodes finish.
        tags: Extra settings stored in every trajectory (policy name, information setting, …).
        static_map: One static map for every episode of this world (e.g. a built-in scenario among
            walls), in place of the scenario's own ``static_map`` attribute.

    Static obstacles: each episode's map (a :class:`~socialnav.static_map.StaticMap`, or None for an
    open floor) comes with the episode: from the episode batch's ``static_maps`` (one per episode)
    when the scenario generates them, else the world's ``static_map`` argument, else the scenario's
    ``static_map`` attribute (one map for all its episodes), else none.
    """

    def __init__(
        self,
        settings: WorldSettings,
        scenario: Scenario,
        batch_size: int,
        *,
        split: str = "test",
        start: int = 0,
        count: int | None = None,
        record: bool = True,
        tags: dict | None = None,
        static_map: StaticMap | None = None,
    ):
        if not isinstance(batch_size, int | np.integer) or batch_size < 1:
            raise ValueError(f"batch_size must be an integer >= 1, got {batch_size!r}")
        self.settings = settings
        self.scenario = scenario
        self.stream = EpisodeStream(scenario, split, start, count)
        B, A = int(batch_size), 1 + int(scenario.n_humans)
        check_world_size(settings, B, A, record)
        self.batch_size, self.n_agents = B, A
        self.position = np.zeros((B, A, 2))
        self.velocity = np.zeros((B, A, 2))
        self.goal = np.zeros((B, A, 2))
        self.radius = np.zeros((B, A))
        self.v_pref = np.zeros((B, A))
        self.mask = np.zeros((B, A), dtype=np.uint8)
        self.theta = np.zeros(B)
        self.steps = np.zeros(B, dtype=np.int32)
        self.status = np.full(B, _core.STATUS_IDLE, dtype=np.int8)
        self.reward = np.zeros(B)
        self.dmin = np.full(B, np.inf)
        self.done = np.zeros(B, dtype=np.uint8)
        self.overlaps = np.zeros(B, dtype=np.int32)
        self.arrival = np.full((B, A), np.nan)
        self.end_step = np.full(B, -1, dtype=np.int32)
        self.collision_kind = np.zeros(B, dtype=np.int8)
        self.episode_index = np.full(B, -1, dtype=np.int64)
        self.episode_seed = np.full(B, -1, dtype=np.int64)
        T = settings.history_length() if record else 0
        hist = (np.zeros((B, T, A, 2)), np.zeros((B, T, A, 2)), np.zeros((B, T))) if record else (None,) * 3
        self._recorder = Recorder(self, *hist, tags or {}) if record else None
        self._core = _core.World(
            self._core_config(B, A, T),
            self.position,
            self.velocity,
            self.goal,
            self.radius,
            self.v_pref,
            self.mask,
            self.theta,
            self.steps,
            self.status,
            self.reward,
            self.dmin,
            self.done,
            self.overlaps,
            self.arrival,
            self.end_step,
            *hist,
            shared_pool(settings.resolved_threads),
            self.collision_kind,
        )
        #: (B,) each slot's static map (None: open floor); change it through `set_static_map` only.
        self.static_maps: list[StaticMap | None] = [None] * B
        self._obstacle_arrays: ObstacleArrays | None = None  # the flat form of static_maps, cached
        self._n_mapped = 0  # slots whose static map is not None (open floors skip the O(B) scan per step)
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(f"static_map must be a StaticMap or None, got {type(static_map).__name__}")
        self._fixed_map = (static_map or None) if static_map is not None else _scenario_map(scenario)
        self._custom_maps: set[int] = set()  # slots whose map is not the scenario's fixed map
        if self._fixed_map is not None:
            for b in range(B):
                self.set_static_map(b, self._fixed_map)
        self._actions = np.zeros((B, 2))
        self._failure = np.zeros(B, dtype=np.int32)  # refill_done's generation codes
        # Built-in scenarios are generated by the core in its worker threads (scenarios/native.py).
        self._native_scenario = native_config(scenario)

    def close(self) -> None:
        """Releases the native world now (not whenever the cycle collector gets to this World).

        The World cannot step afterwards. Also called on leaving a ``with World(...)`` block. Its
        worker threads belong to the process's pool for its thread count (:mod:`socialnav.sim.pool`),
        shared with every other World and native policy, and stay for the next one.
        """
        self._core = None  # the only reference: the native world goes at once
        self._recorder = None  # breaks the World <-> Recorder cycle

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _core_config(self, B: int, A: int, T: int) -> _core.WorldConfig:
        s = self.settings
        c = _core.WorldConfig()
        c.batch, c.agents, c.history_len, c.threads = B, A, T, s.resolved_threads
        c.dt, c.time_limit = s.dt, s.time_limit
        c.human_model = _HUMAN_MODEL_IDS[s.human_model]
        c.robot_visible = s.visibility == "visible"
        c.kinematics = _core.HOLONOMIC if s.kinematics == "holonomic" else _core.UNICYCLE
        c.rotation_limit = s.rotation_limit
        c.crowdsim_compat = s.crowdsim_compat
        c.discomfort_dist = s.reward.discomfort_dist
        c.success_reward = s.reward.success_reward
        c.collision_penalty = s.reward.collision_penalty
        c.discomfort_penalty_factor = s.reward.discomfort_penalty_factor
        c.orca = orca_params(s)
        c.orca_radius_margin = s.orca.radius_margin
        c.human_safety_space = s.orca.safety_space
        c.social_force = social_force_params(s)
        c.continue_after_success = s.continue_after_success
        c.continuation_cap = s.continuation_cap
        c.max_obstacle_vertices = s.max_obstacle_vertices
        c.obstacle_collision_penalty = s.reward.resolved_obstacle_collision_penalty
        c.obstacle_collision_ends = s.obstacle_collision_ends
        return c

    def set_static_map(self, slot: int, static_map: StaticMap | None) -> None:
        """Gives slot ``slot``'s current episode the static map ``static_map`` (None: an open floor);
        the next episode loaded into the slot brings its own (see the class docstring). Raises
        ValueError beyond ``max_obstacle_vertices``."""
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(f"a static map must be a StaticMap or None, got {type(static_map).__name__}")
        static_map = static_map if static_map else None
        if static_map is self.static_maps[slot]:
            self._note_custom(slot, static_map)
            return
        if static_map is not None and static_map.n_vertices > self.settings.max_obstacle_vertices:
            raise ValueError(
                f"the static map of slot {slot} has {static_map.n_vertices} vertices, more than "
                f"max_obstacle_vertices = {self.settings.max_obstacle_vertices} (raise that setting)"
            )
        if static_map is not None:
            need = self.batch_size * static_map.n_vertices * OBSTACLE_VERTEX_BYTES
            if need > MAX_WORLD_BYTES:
                raise ValueError(
                    f"a static map of {static_map.n_vertices} vertices in each of {self.batch_size} slots "
                    f"needs {need / 2**30:.1f} GiB, more than the {MAX_WORLD_BYTES / 2**30:.0f} GiB allowed "
                    "(lower the batch size or simplify the map)"
                )
        if static_map is None:
            vertices, offsets = np.zeros((0, 2)), np.zeros(1, np.int64)
        else:
            vertices, offsets = static_map.to_flat()
        self._core.set_obstacles(int(slot), vertices, offsets)
        self._n_mapped += (static_map is not None) - (self.static_maps[slot] is not None)
        self.static_maps[slot] = static_map
        self._obstacle_arrays = None
        self._note_custom(slot, static_map)

    def _note_custom(self, slot: int, static_map: StaticMap | None) -> None:
        """Tracks the slots whose map is not the world's fixed one (native refills restore it)."""
        if static_map is self._fixed_map:
            self._custom_maps.discard(int(slot))
        else:
            self._custom_maps.add(int(slot))

    @property
    def obstacles(self) -> ObstacleArrays | None:
        """The slots' static maps in flat form (None when every slot is an open floor)."""
        if self._obstacle_arrays is None and self._n_mapped:
            self._obstacle_arrays = ObstacleArrays.from_maps(self.static_maps)
        return self._obstacle_arrays

    # -- episode management -------------------------------------------------------------------
    def reset(self) -> Observation:
        """Fills every slot with the next episodes of the stream and returns the observation."""
        self.status[:] = _core.STATUS_IDLE
        self._fill(np.arange(self.batch_size))
        return self.observe()

    def restart(self, start: int) -> Observation:
        """Restarts the episode stream at index ``start`` and refills every slot from it."""
        self.stream = EpisodeStream(
            self.scenario,
            self.stream.split,
            start,
            None if self.stream.stop is None else max(self.stream.stop - start, 0),
        )
        return self.reset()

    def use_stream(self, stream: EpisodeStream) -> Observation:
        """Replaces the episode stream (same scenario) and refills every slot from it."""
        if stream.scenario is not self.scenario:
            raise ValueError("the stream must hand out episodes of this world's scenario")
        self.stream = stream
        return self.reset()

    @property
    def _generates_natively(self) -> bool:
        """The core generates the stream's next episodes (a built-in scenario, nothing buffered)."""
        return self._native_scenario is not None and not self.stream.buffered

    def _next_episodes(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Indices and seeds of the stream's next ``min(k, remaining)`` episodes (raises as
        :func:`episode_seeds` where they leave the split)."""
        indices = self.stream.take_indices(k) if k else None
        if indices is None:
            return _NO_EPISODES, _NO_EPISODES  # no episode ended (most steps of a small batch)
        return indices, episode_seeds(self.stream.split, indices)

    def _fill(self, slots: np.ndarray) -> None:
        if self._generates_natively:
            self._fill_native(slots)
            return
        episodes = self.stream.take(len(slots))
        n = 0 if episodes is None else len(episodes.indices)
        if n:
            self._load(slots[:n], episodes)
        self.status[slots[n:]] = _core.STATUS_IDLE
        self.episode_index[slots[n:]] = -1

    def _fill_native(self, slots: np.ndarray) -> None:
        """`_fill` for a built-in scenario: the core generates the episodes straight into the slots, in
        its worker threads, bit-identical to ``scenario.generate`` + `_load`."""
        for b in slots:
            if int(b) in self._custom_maps:
                self.set_static_map(int(b), self._fixed_map)
        indices, seeds = self._next_episodes(len(slots))
        n = len(indices)
        if n:
            failure = np.zeros(n, dtype=np.int32)
            self._core.load_generated(
                self._native_scenario, np.ascontiguousarray(slots[:n], dtype=np.int64), seeds, failure
            )
            raise_on_failure(self.scenario, failure, seeds)
            self.episode_index[slots[:n]] = indices
            self.episode_seed[slots[:n]] = seeds
        self.status[slots[n:]] = _core.STATUS_IDLE
        self.episode_index[slots[n:]] = -1

    def _load(self, slots: np.ndarray, ep: EpisodeBatch) -> None:
        for name in (
            "robot_start",
            "robot_goal",
            "robot_theta",
            "robot_radius",
            "robot_v_pref",
            "human_start",
            "human_goal",
            "human_radius",
            "human_v_pref",
        ):
            value = getattr(ep, name)
            if not np.all(np.isfinite(value)):
                bad = np.argwhere(~np.isfinite(value))[0]
                raise ValueError(
                    f"scenario {type(self.scenario).__name__} produced a non-finite {name} "
                    f"for episode index {int(ep.indices[bad[0]])}"
                )
        maps = getattr(ep, "static_maps", None)
        if maps is not None and len(maps) != len(ep.indices):
            raise ValueError(
                f"scenario {type(self.scenario).__name__} produced {len(maps)} static maps for "
                f"{len(ep.indices)} episodes"
            )
        for j, slot in enumerate(slots):
            self.set_static_map(int(slot), self._fixed_map if maps is None else maps[j])
        self.position[slots, 0] = ep.robot_start
        self.position[slots, 1:] = ep.human_start
        self.velocity[slots] = 0.0
        self.goal[slots, 0] = ep.robot_goal
        self.goal[slots, 1:] = ep.human_goal
        self.radius[slots, 0] = ep.robot_radius
        self.radius[slots, 1:] = ep.human_radius
        self.v_pref[slots, 0] = ep.robot_v_pref
        self.v_pref[slots, 1:] = ep.human_v_pref
        self.mask[slots, 0] = 1
        self.mask[slots, 1:] = ep.human_mask
        self.theta[slots] = ep.robot_theta
        self.steps[slots] = 0
        self.reward[slots] = 0.0
        self.dmin[slots] = np.inf
        self.done[slots] = 0
        self.overlaps[slots] = 0
        self.arrival[slots] = np.nan
        self.end_step[slots] = -1
        self.collision_kind[slots] = 0
        self.episode_index[slots] = ep.indices
        self.episode_seed[slots] = ep.seeds
        self.status[slots] = _core.STATUS_RUNNING

    # -- stepping -------------------------------------------------------------------------------
    @property
    def active(self) -> np.ndarray:
        """(B,) slots whose robot still acts."""
        return self.status == _core.STATUS_RUNNING

    @property
    def busy(self) -> bool:
        """True while any slot holds an unfinished episode (running or continuing)."""
        return bool(np.any((self.status == _core.STATUS_RUNNING) | (self.status == _core.STATUS_CONTINUING)))

    def observe(self, oracle: bool = False) -> Observation:
        """The batch's observation; ``oracle`` adds the humans' exact next states (computed once
        per step for all candidate actions, since human motion does not depend on the robot's action)."""
        if self._core is None:
            obs = build_observation(
                self.position,
                self.velocity,
                self.goal,
                self.radius,
                self.v_pref,
                self.mask,
                self.theta,
                self.active,
                self.steps * self.settings.dt,
                self.settings.dt,
                self.settings.kinematics,
            )
            obs = dataclasses.replace(obs, obstacles=self.obstacles)
        else:
            # The same arrays as build_observation, filled by the native core in its worker threads.
            # Fresh arrays every call: callers may keep an observation while the world steps on.
            arrays = self._observation_arrays()
            self._core.observe(*arrays)
            obs = Observation(*arrays, self.settings.dt, self.settings.kinematics, obstacles=self.obstacles)
        if oracle:
            nxt = np.zeros((self.batch_size, self.n_agents - 1, 5))
            self._core.preview_humans(nxt)
            obs = dataclasses.replace(obs, next_humans=nxt)
        return obs

    def _observation_arrays(self, rows: int | None = None) -> tuple[np.ndarray, ...]:
        """Fresh (robot, humans, human_mask, active, time) arrays of ``rows`` rows (B by default) for
        the core to fill: callers may keep an observation while the world steps on."""
        b, n = self.batch_size if rows is None else rows, self.n_agents - 1
        return (
            np.empty((b, ROBOT_DIM)),
            np.empty((b, n, HUMAN_DIM)),
            np.empty((b, n), dtype=bool),
            np.empty(b, dtype=bool),
            np.empty(b),
        )

    def step(
        self, actions: np.ndarray, *, final_observation: bool = False, observe: bool = False
    ) -> StepResult:
        """Advances all slots by dt; finished episodes are recorded and their slots refilled.

        Args:
            actions: (B, 2) robot actions ((vx, vy) holonomic, (v, dθ) unicycle); rows of
                inactive slots are ignored.
            final_observation: Also return the observation of finished slots before their reset.
            observe: Also return the observation after the step (refilled slots included), i.e.
                what :meth:`observe` returns next; a built-in scenario's world writes it in the
                same native pass as the refill, which saves a pass over the batch per step.
        """
        if self._core is None:
            raise RuntimeError("this World is closed")
        actions = np.asarray(actions, dtype=np.float64)
        if actions.shape != (self.batch_size, 2):
            raise ValueError(f"actions must have shape ({self.batch_size}, 2), got {actions.shape}")
        np.copyto(self._actions, actions)
        b = self.batch_size
        reward, final_dmin = np.empty(b), np.empty(b)
        terminated, truncated = np.empty(b, dtype=bool), np.empty(b, dtype=bool)
        outcome_code, final_episode = np.empty(b, dtype=np.int8), np.empty(b, dtype=np.int64)
        collision_kind = np.empty(b, dtype=np.int8)
        # The core writes the per-slot report in its step pass: no Python over the B slots here.
        n_done = self._core.step(
            self._actions, reward, terminated, truncated, outcome_code, final_dmin, final_episode,
            self.episode_index, collision_kind,
        )
        finished: list = []
        final_obs = next_obs = None
        native = self._generates_natively
        # The core writes done as 0/1: a bool scan. The native refill finds the slots itself.
        done_slots = None
        if n_done and (self._recorder is not None or not native or self._custom_maps or
                       (final_observation and self.obstacles)):
            done_slots = self.done.view(bool).nonzero()[0]
        if done_slots is not None and self._recorder is not None:
            finished = self._recorder.collect(done_slots)  # before the refill
        if native:
            if n_done or observe:
                final_obs, next_obs = self._refill_natively(n_done, final_observation, observe, done_slots)
        else:
            if n_done:
                if final_observation:
                    final_obs = self.observe().take(done_slots)
                self._fill(done_slots)
            if observe:
                next_obs = self.observe()
        return StepResult(
            reward, terminated, truncated, finished, final_obs, outcome_code, final_dmin, final_episode,
            next_obs, collision_kind,
        )

    def _refill_natively(
        self, n_done: int, final_observation: bool, observe: bool, done_slots: np.ndarray | None
    ) -> tuple[Observation | None, Observation | None]:
        """Refills the finished slots of a built-in scenario: the core picks the slots, generates and
        loads the stream's next episodes (`_fill_native`'s result, bit for bit) and writes the finished
        slots' final observation and every slot's next one, all in one pass."""
        indices, seeds = self._next_episodes(n_done)
        final = self._observation_arrays(n_done) if final_observation and n_done else None
        nxt = self._observation_arrays() if observe else None
        failed = self._core.refill_done(
            self._native_scenario, indices, seeds, self.episode_index, self.episode_seed, self._failure,
            nxt, final,
        )
        if failed:
            raise_on_failure(self.scenario, self._failure[: len(indices)], seeds)
        dt, kinematics = self.settings.dt, self.settings.kinematics
        walls = self.obstacles
        final_walls = None if walls is None or final is None else walls.take(done_slots)
        if self._custom_maps and done_slots is not None:
            for b in done_slots:  # the new episodes have the scenario's map
                self.set_static_map(int(b), self._fixed_map)
            walls = self.obstacles
        return (
            None if final is None else Observation(*final, dt, kinematics, obstacles=final_walls),
            None if nxt is None else Observation(*nxt, dt, kinematics, obstacles=walls),
        )


_NO_EPISODES = np.zeros(0, dtype=np.int64)  # empty: nothing can be written into it


def _scenario_map(scenario: Scenario) -> StaticMap | None:
    """The scenario's one map for all its episodes (its ``static_map`` attribute), if it has one."""
    fixed = getattr(scenario, "static_map", None)
    if fixed is not None and not isinstance(fixed, StaticMap):
        raise TypeError(
            f"scenario {type(scenario).__name__}.static_map must be a StaticMap or None, "
            f"got {type(fixed).__name__}"
        )
    return fixed if fixed else None


def orca_params(settings: WorldSettings) -> _core.OrcaParams:
    p = _core.OrcaParams()
    p.neighbor_dist = settings.orca.neighbor_dist
    p.max_neighbors = settings.orca.max_neighbors
    p.time_horizon = settings.orca.time_horizon
    p.time_horizon_obst = settings.orca.time_horizon_obst
    return p


def social_force_params(settings: WorldSettings) -> _core.SocialForceParams:
    sf = settings.social_force
    p = _core.SocialForceParams()
    p.relaxation_time, p.v0, p.sigma, p.step_time = sf.relaxation_time, sf.v0, sf.sigma, sf.step_time
    p.fov_half_angle = np.deg2rad(sf.fov_half_angle)
    p.outside_fov_weight, p.max_speed_factor = sf.outside_fov_weight, sf.max_speed_factor
    p.wall_u0, p.wall_r = sf.wall_u0, sf.wall_r
    return p
