"""Scenarios with walls after Francis et al. 2025, Fig. 7.

Francis et al., "Principles and Guidelines for Evaluating Social Robot Navigation Algorithms" (arXiv
2306.16740, ACM THRI 2025).

The paper draws its scenarios without dimensions; every size here is a decision, stated with its
reason in ``docs/walls_maps.md``. Common conventions: the robot and the humans keep the protocol's
0.3 m radius, ``discomfort_dist`` (0.2 m) is the clearance required between placed agents and
between an agent and a wall, R = ``circle_radius`` (4 m) sets the travel distance, the robot walks
from (0, −R) towards +y unless a scenario says otherwise. Corridor walls are zero-thickness wall
segments (a width is then the distance between the wall lines); blocks that an agent cannot enter
(corners, pillars) are solid polygons; the obstruction is a group of standing people.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from socialnav.scenarios.base import HumanArrays, param
from socialnav.scenarios.episode_random import EpisodeRandom
from socialnav.scenarios.registry import register_scenario
from socialnav.scenarios.walls import Flow, WalledScenario, box, polyline

__all__ = [
    "BlindCorner", "EnteringRoom", "ExitingRoom", "FrontalApproach", "Intersection", "NarrowDoorway",
    "NarrowHallway", "PedestrianObstruction",
]

#: The walled scenarios, in the order of Francis et al.'s Fig. 7 (the `francis2023` preset's order); the
#: last, whose pillars are drawn per episode, is in ``circle_pillars.py``.
FRANCIS_SCENARIOS = (
    "frontal_approach", "pedestrian_obstruction", "intersection", "blind_corner", "narrow_hallway",
    "narrow_doorway", "entering_room", "exiting_room", "circle_crossing_obstacles",
)


def _door_fits(scenario: WalledScenario, wall: str) -> None:
    width = getattr(scenario, wall)
    if not (math.isfinite(width) and math.isfinite(scenario.door_width)):
        return  # the settings' own check says which is not finite
    if not scenario.door_width < width:
        raise ValueError(f"{type(scenario).__name__}.door_width must be < {wall} = {width} m, "
                         f"got {scenario.door_width}")


def _corridor_walls(width: float, length: float, end_wall: float) -> list[np.ndarray]:
    """A straight corridor along y between two halls, with walls turning outwards at its ends.

    Its two side walls and, at each end, walls turning outwards (``end_wall`` long each side), so that an
    agent pushed out of the corridor comes back through it instead of walking round the outside of a
    free-standing pair of walls.
    """
    h, half = width / 2, length / 2
    sides = [np.array([[-h, -half], [-h, half]]), np.array([[h, -half], [h, half]])]
    if end_wall <= 0:
        return sides
    return sides + [np.array([[sx * h, sy * half], [sx * (h + end_wall), sy * half]])
                    for sx in (-1, 1) for sy in (-1, 1)]


def _mirror_y(start: np.ndarray) -> np.ndarray:
    return start * np.array([1.0, -1.0])


def _mirror_x(start: np.ndarray) -> np.ndarray:
    return start * np.array([-1.0, 1.0])


@dataclass(frozen=True, kw_only=True)
class _Hallway(WalledScenario):
    """A straight corridor along y; the human walks head-on from (o, R) to (o, −R)."""

    fixed_n_humans = True
    passages = ("corridor_width",)
    #: One human met head-on, so a passing side is defined: M_VI applies (Francis (a) and (j)), and
    #: the evaluation's summary gives it a side-preference row (Table III, one-human encounters).
    passing_side: ClassVar[bool] = True

    n_humans: int = param(1, "humans per episode (always 1 here)", ge=1)
    corridor_width: float = param(1.8, "distance between the two walls", unit="m", gt=0)
    corridor_length: float = param(10.0, "length of the walls, centred on the origin", unit="m", gt=0)
    lateral_jitter: float = param(0.2, "human start and goal offset o ~ U(-j, j) across the corridor",
                                  unit="m", ge=0)
    start_jitter: float = param(0.5, "human start distance R ± U(-j, j) along the corridor", unit="m", ge=0)
    end_wall: float = param(3.0, "length of the hall walls at each end of the corridor, each side (0: none)",
                            unit="m", ge=0)
    exit_distance: float = param(3.0, "how far past the corridor's end the human's goal lies", unit="m", gt=0)

    def cross_check(self) -> None:
        """Also refuses jitter that draws the human beyond the corridor's walls."""
        super().cross_check()
        self.refuse_jitter_beyond_the_corridor()

    def walls(self) -> list[np.ndarray]:
        return _corridor_walls(self.corridor_width, self.corridor_length, self.end_wall)

    def flows(self) -> list[Flow]:
        # The human walks the corridor's whole length and on into the hall (exit_distance past its end):
        # a goal at the robot's start, as in the open-floor `passing`, would park the human in the
        # corridor, and one just past its end (1 m, the earlier goal) parks it in the corridor's mouth,
        # where it leaves less room beside the corner than a robot keeping its safety space needs
        # (docs/walls_maps.md); either blocks the robot for the rest of the episode.
        r, o, s = self.circle_radius, self.lateral_jitter, self.start_jitter
        beyond = self.corridor_length / 2 + self.exit_distance
        return [Flow((-o, o, r - s, r + s), goal=lambda start: np.stack(
            [start[:, 0], np.full(len(start), -beyond)], axis=1))]


@register_scenario("narrow_hallway")
@dataclass(frozen=True, kw_only=True)
class NarrowHallway(_Hallway):
    """Francis (j): head-on in a corridor barely wide enough for two.

    1.8 m = two 0.6 m bodies and three 0.2 m gaps: wall, each other, wall.
    """


@register_scenario("frontal_approach")
@dataclass(frozen=True, kw_only=True)
class FrontalApproach(_Hallway):
    """Francis (a): one human head-on in a wide hall.

    The hall is 4 m wide: the two can pass keeping M_I's outer ε = 1.2 m apart and 0.2 m from the walls, 0.6 +
    1.2 + 0.6 + 2·0.2 = 2.8 m, with room to spare.
    """

    corridor_width: float = param(4.0, "distance between the two walls", unit="m", gt=0)


@register_scenario("pedestrian_obstruction")
@dataclass(frozen=True, kw_only=True)
class PedestrianObstruction(WalledScenario):
    """Francis (b): a standing group of three in the robot's path in a 3 m corridor.

    The group (centres 0.8 m apart: two side by side, the third 0.7 m beyond them as seen from the
    robot; the formation has a fourth place, on the robot's side, for subclasses) stands around
    (c, y_c), c ~ U(−group_offset, group_offset), y_c ~ U(−0.5, 0.5); each human's goal is its start.
    The group spans 1.4 m across, so the wider side leaves 0.8 m + |c| between it and a wall.
    """

    FORMATION: ClassVar[tuple[tuple[float, float], ...]] = ((-0.4, 0.0), (0.4, 0.0), (0.0, 0.7), (0.0, -0.7))

    fixed_n_humans = True

    n_humans: int = param(3, "humans in the standing group (always 3 here)", ge=1)
    corridor_width: float = param(3.0, "distance between the two walls", unit="m", gt=0)
    corridor_length: float = param(10.0, "length of the walls, centred on the origin", unit="m", gt=0)
    group_offset: float = param(0.5, "the group's centre across the corridor ~ U(-g, g)", unit="m", ge=0)
    end_wall: float = param(3.0, "length of the hall walls at each end of the corridor, each side (0: none)",
                            unit="m", ge=0)

    def __post_init__(self) -> None:
        """Validate settings; the formation fixes the group's size and geometry."""
        super().__post_init__()
        if self.n_humans > len(self.FORMATION):
            raise ValueError(f"PedestrianObstruction.n_humans must be <= {len(self.FORMATION)}, "
                             f"got {self.n_humans}")
        if self.randomize_attributes:
            raise ValueError("PedestrianObstruction.randomize_attributes must be False (the group's "
                             "formation is designed for the fixed radius)")
        least = self.least_corridor_width()
        if not self.corridor_width > least:
            span = self.group_span()
            self.refuse("corridor_width", f"must be > {least:.3g} m, or the standing group "
                        f"({span[1] - span[0]:.3g} m across, group_offset = {self.group_offset:g} m) may "
                        "leave no gap beside it wider than the robot's diameter (2 · robot_radius = "
                        f"{2 * self.robot_radius:g} m) and block the route to the goal in {self.name}; "
                        "widen the corridor or make the agents smaller")
        # The group's centre is checked against the robot's start only; its members, up to 0.5 m + the
        # formation's reach along the corridor, must clear the robot's start and goal as every start must.
        ys = [y for _, y in self.FORMATION[: self.n_humans]]
        need = self.robot_radius + self.human_radius + self.discomfort_dist
        clear = min(self.circle_radius - (max(ys) + 0.5), self.circle_radius + (min(ys) - 0.5))
        if clear < need:
            self.refuse("circle_radius", "must leave the standing group (its members up to "
                        f"{max(max(ys), -min(ys)) + 0.5:g} m from the middle along the corridor) at least "
                        f"robot_radius + human_radius + discomfort_dist = {need:.3g} m from the robot's "
                        f"start (0, -R) and goal (0, R); with R = {self.circle_radius:g} m a member can come "
                        f"within {max(clear, 0.0):.3g} m: raise circle_radius")
        placed = self.placement_width()
        if self.corridor_width < placed:
            clearance = self.human_radius + self.discomfort_dist
            self.refuse("corridor_width", f"must be >= {placed:.3g} m, or a group drawn "
                        f"{self.group_offset:g} m (group_offset) off the corridor's centre may stand "
                        f"closer to a wall than human_radius + discomfort_dist = {clearance:.3g} m, and its "
                        f"episodes could not be placed in {self.name}; widen the corridor or lower "
                        "group_offset")

    def placement_width(self) -> float:
        """The corridor width [m] that places the group at any drawn centre.

        Its outer humans' centres, at the largest offset, stay ``human_radius + discomfort_dist`` from
        the walls, as every start must.
        """
        reach = max(abs(x) for x, _ in self.FORMATION[: self.n_humans])
        # rounded so that a width of exactly this one is accepted despite float noise
        return round(2 * (self.group_offset + reach + self.human_radius + self.discomfort_dist), 9)

    def group_span(self) -> tuple[float, float]:
        """The group's extent across the corridor [m], edge to edge, relative to its centre."""
        xs = [x for x, _ in self.FORMATION[: self.n_humans]]
        return min(xs) - self.human_radius, max(xs) + self.human_radius

    def least_corridor_width(self) -> float:
        """The corridor width [m] whose wider gap beside the group is at worst the robot's diameter.

        The wider gap, w/2 + max(lo + c, −hi − c), is least where lo + c = −hi − c, or at the end of
        [−group_offset, group_offset] nearest to that point.
        """
        lo, hi = self.group_span()
        c = float(np.clip(-(lo + hi) / 2, -self.group_offset, self.group_offset))
        # rounded so that a width of exactly the least (2.6 m by default) is refused despite float noise
        return round(2 * (2 * self.robot_radius - max(lo + c, -hi - c)), 9)

    def walls(self) -> list[np.ndarray]:
        """The corridor's walls [m]: (2, 2) segments."""
        return _corridor_walls(self.corridor_width, self.corridor_length, self.end_wall)

    def flows(self) -> list[Flow]:
        """The group's centre, drawn as human 0's standing position; the others keep the formation."""
        g = self.group_offset
        return [Flow((-g, g, -0.5, 0.5), goal=lambda start: start)]

    def sample_humans(self, rng: EpisodeRandom, indices: np.ndarray) -> HumanArrays:
        """Draw the group's centre, then lay the formation around it (standing: goal = start)."""
        centre = self.place_flows(rng, indices, self.flows()).start[:, 0]
        b, n = len(rng), self.n_humans
        start = centre[:, None, :] + np.array(self.FORMATION[:n])[None]
        clear = self._clear_of_walls(self._maps(rng, indices), np.full(b, self.human_radius))
        if not clear(np.repeat(np.arange(b), n), start.reshape(-1, 2)).all():
            raise ValueError(f"{self.name}: the group does not fit between the walls with corridor_width="
                             f"{self.corridor_width} and group_offset={self.group_offset}")
        return HumanArrays(start=start, goal=start.copy(), radius=np.full((b, n), self.human_radius),
                           v_pref=np.full((b, n), self.human_v_pref))


@register_scenario("narrow_doorway")
@dataclass(frozen=True, kw_only=True)
class NarrowDoorway(WalledScenario):
    """Francis (k): a wall across an enclosure at y = 0 with a door; people flow through both ways.

    Door 1.2 m (door_width): wider than one body with its discomfort gaps (0.6 + 2·0.2 m = 1.0 m),
    not wide enough for two bodies with theirs, so people pass one at a time. The closed enclosure
    (x = ±area_width/2, y = ±(R + 1)) makes the door the only way through. Human j walks against the
    robot (from y ∈ [1, R + 0.5] to y ∈ [−R − 0.5, −1]) for even j and with it for odd j.
    """

    passages = ("door_width",)

    n_humans: int = param(4, "humans per episode, alternately against and with the robot", ge=0)
    door_width: float = param(1.2, "width of the door", unit="m", gt=0)
    area_width: float = param(6.0, "distance between the side walls", unit="m", gt=0)

    def cross_check(self) -> None:
        """Also refuses a door that does not fit in its wall (after the settings' own type checks)."""
        super().cross_check()
        _door_fits(self, "area_width")

    def walls(self) -> list[np.ndarray]:
        """The doorway's wall with its gap and the surrounding walls [m]: (2, 2) segments."""
        h, d, length = self.area_width / 2, self.door_width / 2, self.circle_radius + 1.0
        return [np.array([[-h, 0.0], [-d, 0.0]]), np.array([[d, 0.0], [h, 0.0]]),
                *polyline((-h, -length), (h, -length), (h, length), (-h, length), (-h, -length))]

    def flows(self) -> list[Flow]:
        """Humans alternate between the far and the near side of the door."""
        h, r = self.area_width / 2, self.circle_radius
        far, near = (-h, h, 1.0, r + 0.5), (-h, h, -r - 0.5, -1.0)
        return [Flow(far, goal_box=near) if j % 2 == 0 else Flow(near, goal_box=far)
                for j in range(self.n_humans)]


@register_scenario("blind_corner")
@dataclass(frozen=True, kw_only=True)
class BlindCorner(WalledScenario):
    """Francis (i): an L-shaped corridor with a human coming round the corner.

    The robot goes up and turns right, a human comes the other way round the corner. The inner corner is a
    solid block (the occluder); the outer wall a polyline.

    Robot (0, −R) → (R, 0); human start (R ± s, o), goal (o, −R − 2), out of the vertical leg.
    """

    fixed_n_humans = True
    passages = ("corridor_width",)

    n_humans: int = param(1, "humans per episode (always 1 here)", ge=1)
    corridor_width: float = param(2.0, "width of both legs", unit="m", gt=0)
    lateral_jitter: float = param(0.2, "human offset o ~ U(-j, j) across its leg", unit="m", ge=0)
    start_jitter: float = param(0.5, "human start distance R ± U(-j, j) along its leg", unit="m", ge=0)

    def cross_check(self) -> None:
        """Also refuses a corridor too wide for the corner blocks, and jitter beyond its walls."""
        super().cross_check()
        self.refuse_blocks_wider_than_the_layout()
        self.refuse_jitter_beyond_the_corridor()

    def robot_endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """Up the vertical leg, then right along the horizontal one."""
        r = self.circle_radius
        return np.array([0.0, -r]), np.array([r, 0.0])

    def robot_heading(self) -> float:
        """Along the corridor (+y), not towards the goal behind the corner."""
        return float(np.pi / 2)

    def walls(self) -> list[np.ndarray]:
        """The outer wall [m] ((2, 2) segments) and the inner corner, a solid (4, 2) block."""
        h, length = self.corridor_width / 2, self.circle_radius + 1.0
        return [*polyline((-h, -length), (-h, h), (length, h)), box(h, length, -length, -h)]

    def flows(self) -> list[Flow]:
        """One human round the corner and out of the vertical leg, towards the robot's side."""
        # Round the corner and out of the vertical leg (1 m past its end), not to the robot's start,
        # where it would block the leg (see _Hallway.flows).
        r, o, s = self.circle_radius, self.lateral_jitter, self.start_jitter
        beyond = self.circle_radius + 2.0
        return [Flow((r - s, r + s, -o, o), goal=lambda start: np.stack(
            [start[:, 1], np.full(len(start), -beyond)], axis=1))]


@register_scenario("intersection")
@dataclass(frozen=True, kw_only=True)
class Intersection(WalledScenario):
    """Francis (f): two corridors crossing at right angles, a human crossing from the robot's left.

    Four solid corner blocks. Robot (0, −R) → (0, R); human (−R ± s, o) → (R ∓ s, o), so that with equal
    speeds both reach the junction at about the same time.
    """

    fixed_n_humans = True
    passages = ("corridor_width",)

    n_humans: int = param(1, "humans per episode (always 1 here)", ge=1)
    corridor_width: float = param(2.0, "width of both corridors", unit="m", gt=0)
    lateral_jitter: float = param(0.2, "human offset o ~ U(-j, j) across its corridor", unit="m", ge=0)
    start_jitter: float = param(0.5, "human start distance R ± U(-j, j) from the junction", unit="m", ge=0)

    def cross_check(self) -> None:
        """Also refuses a corridor too wide for the corner blocks, and jitter beyond its walls."""
        super().cross_check()
        self.refuse_blocks_wider_than_the_layout()
        self.refuse_jitter_beyond_the_corridor()

    def walls(self) -> list[np.ndarray]:
        """The four solid corner blocks of the crossing: (4, 2) polygons [m]."""
        h, length = self.corridor_width / 2, self.circle_radius + 1.0
        return [box(h, length, h, length), box(-length, -h, h, length), box(-length, -h, -length, -h),
                box(h, length, -length, -h)]

    def flows(self) -> list[Flow]:
        """One human crossing the robot's corridor from its left to the mirrored side."""
        r, o, s = self.circle_radius, self.lateral_jitter, self.start_jitter
        return [Flow((-r - s, -r + s, -o, o), goal=_mirror_x)]


@dataclass(frozen=True, kw_only=True)
class _Room(WalledScenario):
    """A room [−w/2, w/2] × [0, depth] with one door centred in its south wall, open floor outside."""

    fixed_n_humans = True
    entering: ClassVar[bool] = False
    passages = ("door_width",)

    n_humans: int = param(1, "humans per episode (always 1 here)", ge=1)
    room_width: float = param(4.0, "inside width of the room", unit="m", gt=0)
    room_depth: float = param(4.0, "inside depth of the room", unit="m", gt=0)
    door_width: float = param(1.2, "width of the door", unit="m", gt=0)
    outside_distance: float = param(3.0, "distance from the door of the point outside", unit="m", gt=0)

    def cross_check(self) -> None:
        """Also refuses a door that does not fit in its wall, and an outside point in the doorway."""
        super().cross_check()
        _door_fits(self, "room_width")
        least = 0.5 + self.widest_agent()[0] + self.discomfort_dist
        if not self.outside_distance > least:  # the outside points are drawn within 0.5 m of it
            self.refuse("outside_distance", f"must be > {least:.3g} m (0.5 m of drawn spread + radius + "
                        f"discomfort_dist), or the point 'outside' {self.name}'s room lands in its doorway")

    def _inside(self) -> np.ndarray:
        return np.array([0.0, 0.6 * self.room_depth])

    def _outside(self) -> np.ndarray:
        return np.array([0.0, -self.outside_distance])

    def robot_endpoints(self) -> tuple[np.ndarray, np.ndarray]:
        """From outside to inside when entering, the reverse when exiting."""
        return (self._outside(), self._inside()) if self.entering else (self._inside(), self._outside())

    def walls(self) -> list[np.ndarray]:
        w, dep, d = self.room_width / 2, self.room_depth, self.door_width / 2
        return [*polyline((-d, 0.0), (-w, 0.0), (-w, dep), (w, dep), (w, 0.0), (d, 0.0))]

    def flows(self) -> list[Flow]:
        w, dep, out = self.room_width / 2, self.room_depth, self.outside_distance
        inside = (-w, w, 0.5 * dep, dep)  # the back half of the room
        outside = (-w, w, -out - 0.5, -out + 0.5)
        # the human goes the other way through the door
        return [Flow(inside, goal_box=outside) if self.entering else Flow(outside, goal_box=inside)]


@register_scenario("entering_room")
@dataclass(frozen=True, kw_only=True)
class EnteringRoom(_Room):
    """Francis (l): the robot enters a room by its door while a person inside leaves.

    The room is 4 m × 4 m (a small office) with a 1.2 m door.
    """

    entering = True


@register_scenario("exiting_room")
@dataclass(frozen=True, kw_only=True)
class ExitingRoom(_Room):
    """Francis (m): the robot leaves the room by its door while a person outside comes in."""

    entering = False
