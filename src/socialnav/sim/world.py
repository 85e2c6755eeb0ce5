"""The batched World: B episode slots advanced by one native call per step.

Episodes come from an :class:`~socialnav.sim.episode_stream.EpisodeStream` (scenario, split, index
range). A finished episode is recorded as a :class:`~socialnav.trajectory.Trajectory` and its slot is
refilled in place from the stream (auto-reset), so the batch never shrinks until the stream runs dry;
then slots go idle. Because every episode's initial state depends only on its (scenario, split, index)
and episodes never interact, an episode's trajectory is the same whatever the batch size or slot it ran
in.

The World's parts live beside it: the stream (``episode_stream``), the step's report (``step_result``),
the native configuration and size bounds (``world_config``), the slots' static maps (``slot_maps``), the
filling of slots with the stream's next episodes (``slot_filling``).
The names users imported from here still are (``__all__``).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from socialnav import _core
from socialnav.maps.static_map import StaticMap
from socialnav.scenarios import Scenario
from socialnav.scenarios.native import native_config
from socialnav.sim.episode_stream import EpisodeStream
from socialnav.sim.observation import HUMAN_DIM, ROBOT_DIM, Observation, ObstacleArrays, build_observation
from socialnav.sim.pool import shared_pool
from socialnav.sim.python_humans import python_humans
from socialnav.sim.recorder import Recorder
from socialnav.sim.settings import WorldSettings
from socialnav.sim.slot_filling import SlotFilling
from socialnav.sim.slot_maps import SlotMaps, scenario_map
from socialnav.sim.slot_memory import SlotMemory
from socialnav.sim.step_result import StepResult
from socialnav.sim.world_config import (
    MAX_WORLD_BYTES,
    OBSTACLE_VERTEX_BYTES,
    check_world_size,
    orca_params,
    sensing_config,
    social_force_params,
    world_bytes,
    world_config,
)

__all__ = [
    "MAX_WORLD_BYTES",
    "OBSTACLE_VERTEX_BYTES",
    "EpisodeStream",
    "StepResult",
    "World",
    "check_world_size",
    "orca_params",
    "social_force_params",
    "world_bytes",
]

#: (robot, humans, human_mask, active, time): the arrays an Observation starts with, filled by the core,
#: and, with a lidar, its (B, beams) float32 scans.
ObservationArrays = tuple[np.ndarray, ...]



def walls_win_message(scenario: str) -> str:
    """What is said where a ``static_map`` is given for a scenario with walls of its own (World, envs)."""
    return (f"scenario {scenario!r} has walls of its own, which win over static_map: the given map is not "
            "used (docs/walls.md)")

class World(SlotFilling, SlotMemory):
    """B episode slots of (1 robot + N humans) stepped in lockstep by the native core.

    Args:
        settings: Simulator semantics.
        scenario: Where episodes come from.
        batch_size: Number of slots B.
        split: "train", "val" or "test": the episode stream's split (see :class:`EpisodeStream`).
        start: First episode index of the stream.
        count: Number of episodes, or None for all of them: an endless stream on the ``train`` split,
            the rest of the 1000 indices of ``val`` or ``test``, the rest of a finite scenario's episodes
            (a count past the split's end, or a start past the scenario's, is refused at once).
        record: Keep per-episode histories and emit trajectories when episodes finish.
        tags: Extra settings stored in every trajectory (policy name, information setting, …).
        static_map: One static map for every episode of this world (e.g. a built-in scenario among
            walls), in place of the scenario's own ``static_map`` attribute.

    Static obstacles: each episode's map (a :class:`~socialnav.maps.static_map.StaticMap`, or None for an
    open floor) comes with the episode: from the episode batch's ``static_maps`` (one per episode)
    when the scenario generates them, else the world's ``static_map`` argument, else the scenario's
    ``static_map`` attribute (one map for all its episodes), else none.
    """

    def __init__(
        self,
        settings: WorldSettings | dict,
        scenario: Scenario | str,
        batch_size: int,
        *,
        split: str = "test",
        start: int = 0,
        count: int | None = None,
        record: bool = True,
        tags: dict | None = None,
        static_map: StaticMap | None = None,
    ):
        """Allocates the slots and the native world (arguments: see the class); slots start idle.

        ``settings`` may be a dict of WorldSettings fields, ``scenario`` a registered scenario's name
        (with its default parameters).

        Raises:
            ValueError: ``batch_size`` is not a positive integer, or the world would exceed
                :data:`~socialnav.sim.world_config.MAX_WORLD_BYTES`.
            TypeError: ``settings``, ``scenario`` or ``static_map`` (or the scenario's) is of the wrong
                type (the argument is named).
        """
        if isinstance(settings, dict):
            from socialnav.settings import from_dict

            settings = from_dict(WorldSettings, settings, "world")
        elif not isinstance(settings, WorldSettings):
            raise TypeError(f"settings must be a WorldSettings or a dict of its fields, got a "
                            f"{type(settings).__name__}")
        if isinstance(scenario, str):
            from socialnav.scenarios import make_scenario

            scenario = make_scenario(scenario)
        elif not isinstance(scenario, Scenario):
            raise TypeError("scenario must be a Scenario (e.g. make_scenario('circle_crossing', n_humans=5)) "
                            f"or a scenario's name, got a {type(scenario).__name__}")
        if isinstance(batch_size, bool) or not isinstance(batch_size, int | np.integer) or batch_size < 1:
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
        # The core writes each step's sample into these histories (None: not recording).
        hist: tuple[np.ndarray | None, np.ndarray | None, np.ndarray | None] = (None, None, None)
        self._recorder: Recorder | None = None
        if record:
            position_h, velocity_h, dmin_h = np.zeros((B, T, A, 2)), np.zeros((B, T, A, 2)), np.zeros((B, T))
            self._recorder = Recorder(self, position_h, velocity_h, dmin_h, tags or {})
            hist = (position_h, velocity_h, dmin_h)
        # The core steps these arrays in place: the World's state is what the core sees.
        state = (
            self.position, self.velocity, self.goal, self.radius, self.v_pref, self.mask, self.theta,
            self.steps, self.status, self.reward, self.dmin, self.done, self.overlaps, self.arrival,
            self.end_step,
        )
        self._core: _core.World | None = _core.World(
            self._core_config(B, A, T), *state, *hist, shared_pool(settings.resolved_threads),
            self.collision_kind,
        )
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(f"static_map must be a StaticMap or None, got {type(static_map).__name__}")
        if static_map and int(getattr(scenario, "max_obstacle_edges", 0)):
            warnings.warn(walls_win_message(scenario.name), UserWarning, stacklevel=2)
        fixed = (static_map or None) if static_map is not None else scenario_map(scenario)
        self._maps = SlotMaps(B, settings.max_obstacle_vertices, fixed)
        #: (B,) each slot's static map (None: open floor); change it through `set_static_map` only.
        self.static_maps: list[StaticMap | None] = self._maps.maps
        if fixed is not None:
            for b in range(B):
                self.set_static_map(b, fixed)
        self._actions = np.zeros((B, 2))
        self._started = False  # reset() has filled the slots: stepping idle slots is a forgotten reset
        self._failure = np.zeros(B, dtype=np.int32)  # refill_done's generation codes
        # Built-in scenarios are generated by the core in its worker threads (scenarios/native.py).
        self._native_scenario = native_config(scenario)
        # A behaviour written in Python gives the humans' velocities before each native step (or None).
        self._python_humans = python_humans(settings, self._native(), B, A)
        # The robot's perception (docs/perception.md); the episode seeds key its noise and dropout.
        sensing = sensing_config(settings)
        if sensing is not None:
            self._native().set_sensing(sensing, self.episode_seed)

    def close(self) -> None:
        """Releases the native world now (not whenever the cycle collector gets to this World).

        The World cannot step afterwards. Also called on leaving a ``with World(...)`` block. Its
        worker threads belong to the process's pool for its thread count (:mod:`socialnav.sim.pool`),
        shared with every other World and native policy, and stay for the next one.
        """
        self._core = None  # the only reference: the native world goes at once
        self._recorder = None  # breaks the World <-> Recorder cycle

    def __enter__(self) -> World:
        """The World itself (``with World(...) as world:``)."""
        return self

    def __exit__(self, *exc: object) -> None:
        """Closes the World (see :meth:`close`)."""
        self.close()

    def _native(self) -> _core.World:
        """The native world; raises RuntimeError once the World is closed."""
        if self._core is None:
            raise RuntimeError("this World is closed")
        return self._core

    def _core_config(self, B: int, A: int, T: int) -> _core.WorldConfig:
        """The core's configuration for B slots of A agents recording T steps (``world_config``)."""
        return world_config(self.settings, B, A, T)

    def set_static_map(self, slot: int, static_map: StaticMap | None) -> None:
        """Gives slot ``slot``'s current episode a static map.

        The next episode loaded into the slot brings its own (see the class docstring).

        Args:
            slot: The slot, 0 <= slot < B.
            static_map: Its map, or None for an open floor.

        Raises:
            IndexError: ``slot`` is not a slot of this world.
            TypeError: ``static_map`` is neither a StaticMap nor None.
            ValueError: The map has more than ``settings.max_obstacle_vertices`` vertices, or its
                copies in every slot would exceed the memory bound.
        """
        if not 0 <= slot < self.batch_size:
            raise IndexError(f"slot {slot} out of range: this world has {self.batch_size} slots (0 to "
                             f"{self.batch_size - 1})")
        self._maps.set(self._native(), slot, static_map)

    @property
    def obstacles(self) -> ObstacleArrays | None:
        """The slots' static maps in flat form (None when every slot is an open floor)."""
        return self._maps.arrays

    # -- episode management -------------------------------------------------------------------
    def reset(self) -> Observation:
        """Fills every slot with the next episodes of the stream and returns the observation.

        Episodes still in flight are dropped (they were taken from the stream already and are not
        played again), with a warning naming them; :meth:`restart` replays from an index.
        """
        running = (self.status == _core.STATUS_RUNNING) | (self.status == _core.STATUS_CONTINUING)
        if running.any():
            dropped = self.episode_index[running]
            shown = ", ".join(str(int(i)) for i in dropped[:8]) + (" ..." if dropped.size > 8 else "")
            warnings.warn(f"reset() drops {dropped.size} episode(s) in flight (indices {shown}); they are "
                          "not played again: restart(start) replays from an index", UserWarning, stacklevel=2)
        return self._reset()

    def _reset(self) -> Observation:
        self.status[:] = _core.STATUS_IDLE
        self._fill(np.arange(self.batch_size))
        self._started = True
        return self.observe()

    def restart(self, start: int) -> Observation:
        """Restarts the episode stream at index ``start`` and refills every slot from it."""
        self.stream = EpisodeStream(
            self.scenario,
            self.stream.split,
            start,
            None if self.stream.stop is None else max(self.stream.stop - start, 0),
        )
        return self._reset()

    def use_stream(self, stream: EpisodeStream) -> Observation:
        """Replaces the episode stream (same scenario) and refills every slot from it."""
        if stream.scenario is not self.scenario:
            raise ValueError("the stream must hand out episodes of this world's scenario")
        self.stream = stream
        return self._reset()

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
        """The batch's observation.

        Args:
            oracle: Add the humans' exact next states (``next_humans``), computed once per step for
                all candidate actions, since human motion does not depend on the robot's action.

        Returns:
            The observation of the B slots.
        """
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
            obs = self._as_observation(arrays, self.obstacles, self.robot_twist())
        if oracle:
            nxt = np.zeros((self.batch_size, self.n_agents - 1, 5))
            if self._python_humans is not None:
                self._python_humans.give(self)
            self._native().preview_humans(nxt)
            if not self.settings.sensing.exact:
                nxt[~obs.human_mask] = 0.0  # the oracle's next states of the humans the robot detects only
            obs = dataclasses.replace(obs, next_humans=nxt)
        return obs

    def _as_observation(self, arrays: ObservationArrays, walls: ObstacleArrays | None,
                        twist: np.ndarray | None) -> Observation:
        """The Observation of arrays the core filled (``_observation_arrays``') and the robot's twist."""
        robot, humans, human_mask, active, time = arrays[:5]
        lidar = arrays[5] if len(arrays) > 5 else None
        settings = self.settings
        return Observation(robot, humans, human_mask, active, time, settings.dt, settings.kinematics,
                           obstacles=walls, lidar=lidar, robot_twist=twist)

    def _observation_arrays(self, rows: int | None = None) -> ObservationArrays:
        """Fresh (robot, humans, human_mask, active, time) arrays of ``rows`` rows (B by default).

        The core fills them; fresh ones each time, since callers may keep an observation while the
        world steps on.
        """
        b, n = self.batch_size if rows is None else rows, self.n_agents - 1
        arrays: ObservationArrays = (
            np.empty((b, ROBOT_DIM)),
            np.empty((b, n, HUMAN_DIM)),
            np.empty((b, n), dtype=bool),
            np.empty(b, dtype=bool),
            np.empty(b),
        )
        beams = self.settings.sensing.lidar_beams
        return arrays + (np.empty((b, beams), dtype=np.float32),) if beams else arrays

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

        Returns:
            The step's rewards, episode ends and finished episodes (see :class:`StepResult`).

        Raises:
            RuntimeError: The World is closed, or was never reset (its slots are idle).
            ValueError: ``actions`` is not (B, 2).
        """
        core = self._native()
        if not self._started and np.all(self.status == _core.STATUS_IDLE):
            raise RuntimeError("step() before reset(): every slot is idle; call reset() (or restart()) first")
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
        if self._python_humans is not None:
            self._python_humans.give(self)
        n_done = core.step(
            self._actions, reward, terminated, truncated, outcome_code, final_dmin, final_episode,
            self.episode_index, collision_kind,
        )
        finished: list = []
        final_obs = next_obs = None
        native = self._generates_natively
        # The core writes done as 0/1: a bool scan. The native refill finds the slots itself.
        done_slots = None
        if n_done and (self._recorder is not None or not native or self._maps.custom or
                       (final_observation and self.obstacles)):
            done_slots = self.done.view(bool).nonzero()[0]
        if done_slots is not None and self._recorder is not None:
            finished = self._recorder.collect(done_slots)  # before the refill
        if native:
            if n_done or observe:
                final_obs, next_obs = self._refill_natively(n_done, final_observation, observe, done_slots)
        else:
            if done_slots is not None:  # not None exactly when an episode ended (n_done)
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
        """Refills the finished slots of a built-in scenario in one native pass.

        The core picks the slots, generates and loads the stream's next episodes (`_fill_native`'s
        result, bit for bit) and writes the finished slots' final observation and every slot's next one.
        """
        indices, seeds = self._next_episodes(n_done)
        final = self._observation_arrays(n_done) if final_observation and n_done else None
        # The finished episodes' twist, read before their slots are refilled (the core's final rows are
        # the finished slots in order).
        final_twist = self.robot_twist(new_at_rest=False) if final is not None else None
        if final_twist is not None:
            final_twist = final_twist[self.done.view(bool)]
        nxt = self._observation_arrays() if observe else None
        walls = self.obstacles
        final_walls = None if walls is None or final is None or done_slots is None else walls.take(done_slots)
        if self._maps.custom and done_slots is not None:
            # The new episodes have the fixed map: given back before the core loads (and checks) them.
            self._maps.restore_fixed(self._native(), done_slots)
            walls = self.obstacles
        failed = self._native().refill_done(
            self._native_scenario, indices, seeds, self.episode_index, self.episode_seed, self._failure,
            nxt, final,
        )
        if failed:
            rows = np.flatnonzero(self._failure[: len(indices)])
            # The core wrote the failed episodes' indices into their slots too.
            slots = np.array([np.flatnonzero(self.episode_index == indices[j])[0] for j in rows])
            self._raise_on_load_failure(slots, indices[rows], seeds[rows], self._failure[rows])
        return (
            None if final is None else self._as_observation(final, final_walls, final_twist),
            None if nxt is None else self._as_observation(nxt, walls, self.robot_twist()),
        )

