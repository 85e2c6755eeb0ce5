"""What the Gymnasium envs share: their construction, their observation, their actions and spaces.

The construction is the world's settings, the scenario, the map and the episode set; the observation is
composed of named parts, and actions are converted to the world's.

Observations are dicts composed of named observation parts (:mod:`socialnav.sim.parts`); by default
(:data:`RAW_PARTS`) ``robot`` (9,), ``humans`` (N, 5) and ``human_mask`` (N,) (see
:mod:`socialnav.sim.observation`), and in worlds with walls (``max_obstacle_edges`` > 0) ``obstacles``
(E, 4), the episode's obstacle edges (x1, y1, x2, y2), zero-padded, and ``obstacle_mask`` (E,): the world's
own arrays, world frame, SI units, float64. ``observation_parts`` composes others (a part registered from
outside the package adds its keys; docs/extending.md).
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from gymnasium import spaces

from socialnav.envs.episode_order import EpisodeOrder
from socialnav.maps.static_map import StaticMap
from socialnav.scenarios import make_scenario
from socialnav.scenarios.base import SPLIT_SIZE
from socialnav.settings import from_dict
from socialnav.sim.actions import discrete_actions
from socialnav.sim.observation import Observation
from socialnav.sim.parts.base import PartContext, PartInput
from socialnav.sim.parts.composition import ObservationComposition
from socialnav.sim.settings import WorldSettings
from socialnav.sim.world import EpisodeStream, walls_win_message

OUTCOME_CODES = {"running": 0, "success": 1, "collision": 2, "timeout": 3}
#: The raw envs' observation parts unless ``observation_parts`` names others.
RAW_PARTS: tuple[str, ...] = ("robot", "humans", "obstacle_edges")
#: The parts the env itself reads (its recorder, the learner wrappers): every composition has them.
REQUIRED_PARTS: tuple[str, ...] = ("robot", "humans")


def raw_composition(
    n_humans: int, kinematics: str, max_edges: int = 0, parts: Sequence[str] = RAW_PARTS, sensing: Any = None
) -> ObservationComposition:
    """The raw env's observation: ``parts`` in the world's own layout (world frame, SI units, float64).

    Raises:
        ValueError: ``parts`` lacks ``robot`` or ``humans``, names a part twice or one that has no world
            frame.
        UnknownObservationPartError: A part name no part has.
    """
    parts = tuple(parts)
    missing = [p for p in REQUIRED_PARTS if p not in parts]
    if missing:
        raise ValueError(f"observation_parts {list(parts)} lacks {', '.join(missing)}: the env's recorder "
                         "and the learner wrappers read the robot and the humans")
    return ObservationComposition(parts, PartContext.for_raw_env(n_humans, kinematics, max_edges, sensing))


def default_raw_parts(settings: WorldSettings) -> tuple[str, ...]:
    """The raw env's parts when ``observation_parts`` is not given.

    :data:`RAW_PARTS`, ``lidar`` when the world has one, ``robot_twist`` for a differential drive.
    """
    return (RAW_PARTS + (("lidar",) if settings.sensing.lidar_beams else ())
            + (("robot_twist",) if settings.kinematics == "diff_drive" else ()))


def observation_and_action_spaces(
    n_humans: int, settings: WorldSettings, v_pref: float, action_set: str, max_edges: int = 0,
    parts: Sequence[str] = RAW_PARTS,
):
    """The env's observation and action spaces (a SB3 model's saved spaces are checked against them)."""
    observation_space = raw_composition(n_humans, settings.kinematics, max_edges, parts,
                                        settings.sensing).single_space()
    if action_set == "discrete":
        action_space: spaces.Space = spaces.Discrete(81)
    elif settings.kinematics == "holonomic":
        action_space = spaces.Box(-v_pref, v_pref, shape=(2,), dtype=np.float64)
    else:  # (v, dθ); a differential drive backs up at most at its max_reverse_speed
        low = -settings.diff_drive.max_reverse_speed if settings.kinematics == "diff_drive" else -v_pref
        action_space = spaces.Box(
            np.array([low, -settings.rotation_limit]),
            np.array([v_pref, settings.rotation_limit]),
            dtype=np.float64,
        )
    return observation_space, action_space


def maps_of(obs: Observation) -> tuple:
    """(B,) each row's static map (None: open floor), for wrappers that encode the walls themselves."""
    return obs.obstacles.maps if obs.obstacles is not None else (None,) * obs.batch_size


class EnvConfig:
    """Shared construction of the world's settings and scenario from keyword arguments."""

    def __init__(
        self,
        scenario: str,
        scenario_params: dict | None,
        world: dict | WorldSettings | None,
        split: str,
        action_set: str,
        preset: Any = None,
        static_map: StaticMap | dict | str | os.PathLike | None = None,
        max_obstacle_edges: int | None = None,
        observation_parts: Sequence[str] | None = None,
    ):
        if action_set not in ("continuous", "discrete"):
            raise ValueError(f"action_set must be 'continuous' or 'discrete', got {action_set!r}")
        if isinstance(static_map, dict):
            static_map = StaticMap.from_dict(static_map)
        elif isinstance(static_map, str | os.PathLike):
            from socialnav.maps.files import load_map

            static_map = load_map(os.fspath(static_map))
        if static_map is not None and not isinstance(static_map, StaticMap):
            raise TypeError(
                "static_map must be a StaticMap, its dict form, a map file path or None, got "
                f"{type(static_map).__name__}"
            )
        self.static_map = static_map or None
        if max_obstacle_edges is not None and (
            not isinstance(max_obstacle_edges, int | np.integer) or max_obstacle_edges < 0
        ):
            raise ValueError(f"max_obstacle_edges must be an integer >= 0, got {max_obstacle_edges!r}")
        if preset is not None:
            scenario_params, world = _preset_defaults(preset, scenario, scenario_params, world)
        self.settings = (
            world if isinstance(world, WorldSettings) else from_dict(WorldSettings, world, "world")
        )
        if self.settings.continue_after_success:
            # The protocol's M_III continuation runs the humans on after the robot's success, with the
            # robot parked: an env's episode is the robot's, which ends at its success.
            raise ValueError("world.continue_after_success: the evaluation's M_III continuation, not an "
                             "environment setting (an env episode ends at the robot's success); leave it "
                             "false")
        self.scenario = make_scenario(scenario, **(scenario_params or {}))
        # A scenario with walls of its own (which win over static_map, as in World) bounds its maps' edges.
        own = int(getattr(self.scenario, "max_obstacle_edges", 0))
        if own and self.static_map is not None:
            import warnings

            warnings.warn(walls_win_message(scenario), UserWarning, stacklevel=3)
            self.static_map = None  # said once, here: the World is not given it
        edges = own if own else (0 if self.static_map is None else len(self.static_map.edges()[0]))
        #: The episodes have walls: the observation should show them.
        self.has_walls = edges > 0
        if max_obstacle_edges is None:
            max_obstacle_edges = edges
        if edges > max_obstacle_edges:
            whose = f"scenario {scenario!r}'s maps have up to" if own == edges else "static_map has"
            raise ValueError(f"{whose} {edges} edges, more than max_obstacle_edges = {max_obstacle_edges}")
        self.max_edges = int(max_obstacle_edges)
        self.split = split
        self.action_set = action_set
        self.v_pref = float(self.scenario.robot_v_pref)
        self.table = discrete_actions(self.settings.kinematics, self.v_pref, self.settings.rotation_limit)
        given = observation_parts
        if isinstance(given, str):  # tuple() would split it into letters
            raise TypeError(f"observation_parts must be a list of part names, got the text {given!r} (write "
                            f"[{given!r}])")
        self.parts = default_raw_parts(self.settings) if given is None else tuple(given)
        #: The env's observation: the parts, composed in the world's own layout.
        self.composition = raw_composition(self.scenario.n_humans, self.settings.kinematics, self.max_edges,
                                           self.parts, self.settings.sensing)
        # Episodes available: a finite scenario's set, the val/test split's range, or endless (train).
        n = self.scenario.n_episodes
        if n is not None and split != "train" and n > SPLIT_SIZE:  # refused here, not at episode 1000
            raise ValueError(f"scenario {scenario!r} has {n} episodes, more than the {SPLIT_SIZE} of split "
                             f"{split!r} (fewer repeats, or split='train')")
        self.n_episodes = n if n is not None else (None if split == "train" else SPLIT_SIZE)

    def observation(self, obs: Observation) -> dict[str, np.ndarray]:
        """The (B, …) arrays of the env's observation of the world's ``obs``."""
        return self.composition(PartInput.from_observation(obs))

    def spaces(self) -> tuple[Any, Any]:
        """One episode's observation and action spaces."""
        return observation_and_action_spaces(self.scenario.n_humans, self.settings, self.v_pref,
                                             self.action_set, self.max_edges, self.parts)

    def order(self, *, seed: int | None = None, start: int | None = None) -> EpisodeOrder:
        """The episode order of seed ``seed``, or from episode ``start`` (:class:`EpisodeOrder`)."""
        return EpisodeOrder(self.n_episodes, seed=seed, start=start)

    def stream(self, order: EpisodeOrder, position: int, count: int | None = None) -> EpisodeStream:
        """The world's episode stream playing ``order`` from stream position ``position``."""
        return EpisodeStream(self.scenario, self.split, position, count, index_map=order)

    def to_actions(self, action: Any, n_envs: int | None = None) -> np.ndarray:
        """The world's (B, 2) actions from one env's action (``n_envs`` None) or a vector env's.

        The shape must be the action space's ((2,) or an index; (n_envs, 2) or (n_envs,) for a vector
        env); a discrete index must be an integer, not a float or bool that would be cast silently.
        """
        if action is None:
            raise ValueError("action is None: step() needs an action of the env's action space")
        raw = np.asarray(action)
        if self.action_set == "discrete":
            expected: tuple[int, ...] = () if n_envs is None else (n_envs,)
            if raw.shape != expected and not (n_envs is None and raw.shape == (1,)):
                raise ValueError(f"discrete action of shape {raw.shape}: expected {expected or 'a scalar'} "
                                 "(action indices)")
            if raw.dtype.kind not in "iu":
                raise ValueError(f"discrete action {action!r}: expected integer indices, got {raw.dtype}")
            index = raw.astype(np.int64).reshape(-1)
            if np.any((index < 0) | (index >= len(self.table))):
                raise ValueError(f"discrete action out of range [0, {len(self.table)}): {index}")
            return self.table[index]
        expected = (2,) if n_envs is None else (n_envs, 2)
        if raw.shape != expected:
            raise ValueError(f"action of shape {raw.shape}: expected {expected} (the action space's shape"
                             + ("" if n_envs is None else ", one action per env") + ")")
        try:
            return raw.astype(np.float64).reshape(-1, 2)
        except (TypeError, ValueError):
            raise ValueError(f"action {action!r}: expected numbers, got {raw.dtype}") from None


def _preset_defaults(preset: Any, scenario: str, scenario_params: dict | None, world: Any):
    """Scenario parameters and world settings of a protocol preset (explicit arguments win).

    A ``world`` dict overrides the preset's world key by key, and within a section (``sensing``,
    ``reward``, ...) field by field: ``world={"sensing": {"lidar_beams": 8}}`` adds a lidar to the preset's
    detections.
    """
    from socialnav.presets import Preset, load_preset

    p = preset if isinstance(preset, Preset) else load_preset(preset)
    default = make_scenario(scenario)
    single = scenario in p.evaluation.single_human or default.n_episodes is not None
    params: dict[str, Any] = {"robot_v_pref": p.robot.v_pref, "robot_radius": p.robot.radius}
    if single:
        params.update(n_humans=1, repeats=p.evaluation.repeats)
    elif not default.fixed_n_humans:  # as the evaluation's cells: a designed crowd keeps its own count
        params["n_humans"] = p.evaluation.n_humans
    params.update(scenario_params or {})
    if world is None:
        world = p.world
    elif not isinstance(world, WorldSettings):
        # a section given (sensing, reward, ...) overrides the preset's key by key, not whole
        merged = dataclasses.asdict(p.world)
        for key, value in dict(world).items():
            section = getattr(p.world, key, None)
            if dataclasses.is_dataclass(section) and isinstance(value, Mapping):
                merged[key] = {**merged[key], **dict(value)}
            else:
                merged[key] = value
        world = merged
    return params, world


def check_options(options: dict[str, Any] | None) -> dict[str, Any]:
    """The reset options as a dict (only ``index`` is known).

    Raises:
        ValueError: An unknown option, named.
    """
    options = dict(options or {})
    unknown = sorted(set(options) - {"index"})
    if unknown:
        raise ValueError(f"unknown reset option(s) {', '.join(unknown)}; valid: index")
    return options
