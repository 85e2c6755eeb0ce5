"""Shared machinery of the scenarios with walls (`socialnav.scenarios.francis`, `circle_pillars`).

The layout, the placement of agents clear of the walls, and the geometry helpers that build the layouts.

A walled scenario declares its layout (a :class:`~socialnav.maps.static_map.StaticMap`, fixed by the
settings, or drawn per episode), the robot's start and goal, and per human a *flow*: a box its start
is drawn from and how its goal follows. Placement is CrowdSim's rejection rule extended by the
walls: a start is redrawn while it lies closer than ``r + r_other + discomfort_dist`` to the robot's
start or another start, or closer than ``r + discomfort_dist`` to a wall; goals likewise against the
robot's goal, the other goals and the walls. After ``max_attempts`` redraws the scene is declared
impossible (:class:`~socialnav.scenarios.ScenarioGenerationError`, naming the human and the seeds).
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from socialnav.maps.static_map import MapStack, StaticMap
from socialnav.scenarios._placement import rejection_sample
from socialnav.scenarios.base import STREAM_GOAL, STREAM_START, HumanArrays, Scenario
from socialnav.scenarios.episode_random import EpisodeRandom

__all__ = ["Flow", "WalledScenario", "box", "polyline"]

#: Key stream of per-episode obstacle draws (the streams of scenarios/base.py use 1-5).
STREAM_OBSTACLES = 6


def box(x0: float, x1: float, y0: float, y1: float) -> np.ndarray:
    """A solid axis-aligned rectangle [x0, x1] × [y0, y1], counter-clockwise (4, 2) [m]."""
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], dtype=np.float64)


def polyline(*points: tuple[float, float]) -> list[np.ndarray]:
    """Wall segments joining consecutive points: a wall with corners."""
    pts = np.array(points, dtype=np.float64)
    return [pts[i : i + 2] for i in range(len(pts) - 1)]


@dataclass(frozen=True)
class Flow:
    """Where one human starts and where it goes.

    Attributes:
        start_box: (x0, x1, y0, y1) [m]: the start is drawn uniformly in it.
        goal: ``goal(start) -> goal`` [(B, 2) m] for a goal that follows from the start (a mirror
            image, the same point for a standing human), or None to draw it in ``goal_box``.
        goal_box: (x0, x1, y0, y1) [m] when ``goal`` is None.
    """

    start_box: tuple[float, float, float, float]
    goal: Callable[[np.ndarray], np.ndarray] | None = None
    goal_box: tuple[float, float, float, float] | None = None


@dataclass(frozen=True, kw_only=True)
class WalledScenario(Scenario):
    """A scenario whose episodes have walls: subclasses give `layout`, `robot_endpoints` and `flows`.

    The layout is fixed by the settings unless `maps_per_episode` is overridden. Settings whose
    layout covers the robot's start or goal, or whose `passages` are too narrow for an agent, are
    refused on construction (ValueError naming them).
    """

    #: The width settings of the passages (doors, corridors) that the robot and the humans go through.
    passages: ClassVar[tuple[str, ...]] = ()

    def cross_check(self) -> None:
        """Also refuses a passage that the largest agent going through it does not fit in.

        The least width is that agent's diameter, excluded: at exactly the diameter it would touch both
        sides, with no room to steer.

        Raises:
            ConfigError: naming the width setting, its value and the least width.
        """
        super().cross_check()
        radius, setting = self.widest_agent()
        for name in self.passages:
            if not getattr(self, name) > 2.0 * radius:
                self.refuse(name, f"must be > {2.0 * radius:g} m, the diameter of the largest agent that "
                            f"goes through it ({setting} = {radius:g} m): a narrower one blocks the route "
                            f"to the goal in {self.name}; widen {name} or make the agents smaller")

    def refuse_blocks_wider_than_the_layout(self) -> None:
        """Refuses a corridor so wide that the solid corner blocks beside it vanish or turn inside out.

        The blocks reach ``circle_radius + 1`` from the centre; a half-width of ``circle_radius`` or
        more would leave blocks under 1 m, or none, and the route would not need the corner.

        Raises:
            ConfigError: naming corridor_width, its value and the bound.
        """
        if not self.corridor_width < 2.0 * self.circle_radius:
            self.refuse("corridor_width", f"must be < 2 x circle_radius = {2.0 * self.circle_radius:g} m: "
                        f"the corner blocks of {self.name} reach circle_radius + 1 m from the centre, and a "
                        "wider corridor leaves them under 1 m or none; narrow the corridor or raise "
                        "circle_radius")

    def refuse_jitter_beyond_the_corridor(self) -> None:
        """Refuses people drawn beyond the corridor's walls, or a corridor too narrow to place anyone.

        A corridor whose middle is closer to the walls than a person may start is refused. Draws near a
        wall are rejected and drawn again (every start must clear the walls by radius + discomfort_dist);
        one past the wall, clear of it on the outside, would be kept.

        Raises:
            ConfigError: naming corridor_width or lateral_jitter, its value and the bound.
        """
        margin = self.widest_agent()[0] + self.discomfort_dist
        half = self.corridor_width / 2
        if half <= margin:  # not even the corridor's middle clears the walls: the width is the problem
            self.refuse("corridor_width", f"must be > {2 * margin:.3g} m (2 x (radius + discomfort_dist)): "
                        f"a person in the middle of {self.name}'s corridor would be closer to a wall than "
                        "that, and its episodes could not be placed")
        if not self.lateral_jitter < half + margin:
            self.refuse("lateral_jitter", f"must be < corridor_width / 2 + radius + discomfort_dist = "
                        f"{half + margin:.3g} m: a larger offset draws people beyond the walls of "
                        f"{self.name}; lower it or widen the corridor")

    def widest_agent(self) -> tuple[float, str]:
        """The largest radius among the robot and the humans [m], and the setting that gives it."""
        if self.randomize_attributes:
            human = (self.random_radius_range[1], "the largest of random_radius_range")
        else:
            human = (self.human_radius, "human_radius")
        return max((self.robot_radius, "robot_radius"), human, key=lambda pair: pair[0])

    def __post_init__(self) -> None:
        """Validate settings, then check that the robot's start and goal clear the fixed layout."""
        super().__post_init__()
        smap = self.layout
        if smap is None:
            return
        need = self.robot_radius + self.discomfort_dist
        for name, point in zip(("start", "goal"), self.robot_endpoints(), strict=True):
            d = float(smap.distance(np.asarray(point, dtype=np.float64)))
            if d < need:
                raise ValueError(
                    f"{type(self).__name__}: the robot's {name} {np.asarray(point).tolist()} is {d:.3g} m "
                    f"from a wall, less than robot_radius + discomfort_dist = {need:.3g} m; the settings "
                    f"{self._geometry_settings()} leave no room for it")

    def __getstate__(self) -> dict[str, object]:
        """Pickled without the per-batch caches (scenarios travel to sweep workers)."""
        return {k: v for k, v in self.__dict__.items() if k not in ("_map_cache", "_stack_cache")}

    def _geometry_settings(self) -> str:
        # dataclasses.fields leaves out the ClassVars (passages, entering, ...), which are no settings
        own = [f.name for f in dataclasses.fields(self) if f.name not in Scenario.__dataclass_fields__]
        return ", ".join(f"{f}={getattr(self, f)!r}" for f in own) or "(defaults)"

    # ---- what subclasses declare ----------------------------------------------------------------
    @functools.cached_property
    def layout(self) -> StaticMap | None:
        """The map of every episode (built once per scenario object), or None when drawn per episode."""
        return StaticMap.from_polygons(self.walls())

    @property
    def max_obstacle_edges(self) -> int:
        """The most obstacle edges an episode's map can have: the fixed layout's.

        Scenarios that draw their maps per episode override it (the Gymnasium envs pad the observed
        edges to it).
        """
        layout = self.layout
        return 0 if layout is None else len(layout.edges()[0])

    def walls(self) -> list[np.ndarray]:
        """The polygons of the fixed layout [m] (see `box` and `polyline`)."""
        raise NotImplementedError

    def flows(self) -> list[Flow]:
        """One `Flow` per human, in human order (len == n_humans)."""
        raise NotImplementedError

    def maps_per_episode(self, rng: EpisodeRandom, indices: np.ndarray) -> tuple[StaticMap, ...]:
        """The map of each episode; the fixed layout for all by default."""
        return (self.layout,) * len(indices)

    # ---- Scenario hooks --------------------------------------------------------------------------
    def static_maps(self, rng: EpisodeRandom, indices: np.ndarray) -> tuple[StaticMap, ...]:
        """Every episode's map: `maps_per_episode`, memoised per batch for `sample_humans`."""
        return self._maps(rng, indices)

    def _maps(self, rng: EpisodeRandom, indices: np.ndarray) -> tuple[StaticMap, ...]:
        # generate() asks for humans first, then for the maps: draw them once per batch
        key = (tuple(int(s) for s in rng.seeds), tuple(int(i) for i in indices))
        cache = self.__dict__.setdefault("_map_cache", {})
        if key not in cache:
            cache.clear()
            cache[key] = self.maps_per_episode(rng, indices)
        return cache[key]

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Place every human of its flow by rejection against the agents and the walls."""
        flows = self.flows()
        if len(flows) != self.n_humans:
            raise ValueError(f"{type(self).__name__}: {len(flows)} flows for n_humans={self.n_humans}")
        return self.place_flows(rng, indices, flows)

    def place_flows(self, rng: EpisodeRandom, indices: np.ndarray, flows: list[Flow]) -> HumanArrays:
        """One human per flow, placed by rejection (see the module docstring)."""
        b, n = len(rng), len(flows)
        maps = self._maps(rng, indices)
        robot_start, robot_goal = (np.broadcast_to(np.asarray(p, dtype=np.float64), (b, 2))
                                   for p in self.robot_endpoints())
        start = np.zeros((b, n, 2))
        goal = np.zeros((b, n, 2))
        radius = np.zeros((b, n))
        v_pref = np.zeros((b, n))
        starts_ref = np.zeros((b, 1 + n, 2))
        goals_ref = np.zeros((b, 1 + n, 2))
        starts_ref[:, 0], goals_ref[:, 0] = robot_start, robot_goal
        ref_rad = np.zeros((b, 1 + n))
        ref_rad[:, 0] = self.robot_radius
        for j, flow in enumerate(flows):
            radius[:, j], v_pref[:, j] = self.human_attributes(rng, j)
            clear = self._clear_of_walls(maps, radius[:, j])
            place = functools.partial(rejection_sample, rng, j=j, radius=radius[:, j],
                                      ref_radius=ref_rad[:, : 1 + j], margin=self.discomfort_dist,
                                      max_attempts=self.max_attempts, accept=clear)
            start[:, j] = place(_uniform_in(flow.start_box), stream=STREAM_START,
                                ref_pos=starts_ref[:, : 1 + j], what=f"{self.name}: start of human {j}")
            if flow.goal is not None:
                goal[:, j] = flow.goal(start[:, j])
                bad = ~clear(np.arange(b), goal[:, j])
                if bad.any():
                    i = int(np.flatnonzero(bad)[0])
                    raise ValueError(f"{self.name}: goal of human {j} {goal[i, j].tolist()} (from its "
                                     f"start {start[i, j].tolist()}, seed {int(rng.seeds[i])}) is too close "
                                     "to a wall")
            else:
                assert flow.goal_box is not None
                goal[:, j] = place(_uniform_in(flow.goal_box), stream=STREAM_GOAL,
                                   ref_pos=goals_ref[:, : 1 + j], what=f"{self.name}: goal of human {j}")
            starts_ref[:, 1 + j], goals_ref[:, 1 + j] = start[:, j], goal[:, j]
            ref_rad[:, 1 + j] = radius[:, j]
        return HumanArrays(start=start, goal=goal, radius=radius, v_pref=v_pref)

    def _clear_of_walls(self, maps: tuple[StaticMap, ...], radius: np.ndarray
                        ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """``accept(rows, points)``: True where a point is ``radius + discomfort_dist`` from every wall."""
        margin = self.discomfort_dist
        shared = all(m is maps[0] for m in maps)
        stack = None if shared else self._stack(maps)

        def accept(rows: np.ndarray, points: np.ndarray) -> np.ndarray:
            need = radius[rows] + margin
            if stack is None:
                return maps[0].distance(points) >= need
            return stack.take(rows).distance(points) >= need

        return accept


    def _stack(self, maps: tuple[StaticMap, ...]) -> MapStack:
        """The stacked maps of a batch, built once for all its humans and attempts."""
        held = self.__dict__.get("_stack_cache")
        if held is None or held[0] is not maps:
            held = (maps, MapStack(maps))  # holding ``maps`` keeps its identity from being reused
            self.__dict__["_stack_cache"] = held
        return held[1]


def _uniform_in(bounds: tuple[float, float, float, float]
                ) -> Callable[[EpisodeRandom, tuple[int, ...], np.ndarray], np.ndarray]:
    x0, x1, y0, y1 = bounds

    def draw(sub: EpisodeRandom, key: tuple[int, ...], rows: np.ndarray) -> np.ndarray:
        u = sub.random(key, 2)
        return np.stack([x0 + (x1 - x0) * u[:, 0], y0 + (y1 - y0) * u[:, 1]], axis=1)

    return draw
