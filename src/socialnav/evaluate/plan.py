"""What a protocol run consists of: cells (policy × scenario × visibility) split into chunks."""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

from socialnav.presets import Preset
from socialnav.scenarios import Scenario, get_scenario, make_scenario
from socialnav.scenarios.seeds import SPLIT_SIZE
from socialnav.settings import ConfigError
from socialnav.sim.settings import WorldSettings

#: Episodes per cell at most (a run of this size takes days; larger is a typo).
MAX_EPISODES = 10_000_000


@dataclass(frozen=True)
class Cell:
    """One (scenario, visibility) pass of the protocol."""

    scenario: str
    visibility: str
    episodes: int
    single_human: bool

    @property
    def key(self) -> str:
        """The cell's name in result files: ``<scenario>__<visibility>``."""
        return f"{self.scenario}__{self.visibility}"

    def chunks(self, size: int) -> list[tuple[int, int]]:
        """The cell's episodes as ``[start, stop)`` ranges of at most ``size`` (the result chunks)."""
        return [(start, min(start + size, self.episodes)) for start in range(0, self.episodes, size)]


def multi_human_scenarios(cells: Sequence[Cell]) -> list[str]:
    """The run's multi-human scenarios, which Table II pools.

    Every scenario it evaluated that is not a single-human one: a ``--scenario`` list may name ones
    outside the preset's ``multi_human``.
    """
    return list(dict.fromkeys(c.scenario for c in cells if not c.single_human))


def plan_cells(preset: Preset, scenarios: list[str] | None = None, episodes: int | None = None,
               visibility: str | None = None) -> list[Cell]:
    """The cells of a run; ``scenarios``/``episodes``/``visibility`` override the preset's.

    Multi-human scenarios run invisible (all metrics) and, for ``both``/``visible``, visible (M_III,
    with the continuation after the robot's arrival). Single-human sweeps (M_VI) run invisible;
    their size is 20 offsets × repeats (``episodes`` caps it for quick runs).
    """
    ev = preset.evaluation
    visibility = visibility or ev.visibility
    passes = ("invisible", "visible") if visibility == "both" else (visibility,)
    if visibility not in ("invisible", "visible", "both"):
        raise ConfigError(f"visibility must be invisible, visible or both, got {visibility!r}")
    if episodes is not None and episodes < 1:
        raise ConfigError(f"episodes must be >= 1, got {episodes}")
    if episodes is not None and episodes > MAX_EPISODES:
        raise ConfigError(f"episodes must be <= {MAX_EPISODES}, got {episodes}")
    names = list(scenarios) if scenarios else [*ev.multi_human, *ev.single_human]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ConfigError(f"scenario(s) {', '.join(repeated)} given more than once")
    for name in names:
        get_scenario(name)  # unknown names raise, listing the valid ones
    cells = []
    for name in names:
        single = name in ev.single_human or _is_single_human(name)
        if single:
            if "invisible" not in passes:
                warnings.warn(f"{name} is a single-human scenario, evaluated with an invisible robot only "
                              f"(M_VI): --visibility {visibility} leaves it out", UserWarning, stacklevel=2)
            else:
                scenario = make_single(preset, name)
                n = scenario.n_episodes
                offsets = getattr(scenario, "offsets", None)
                if episodes and episodes < n and offsets is not None and episodes < len(offsets):
                    # episode i has offset i: the first ones lie on one side of the grid
                    warnings.warn(
                        f"{name}: {episodes} of its {len(offsets)} lateral offsets (episodes 0-"
                        f"{episodes - 1}: {offsets[0]:+.2f} to {offsets[episodes - 1]:+.2f} m), so its side "
                        f"preference (M_VI, Table III) covers only part of the grid; run {len(offsets)} or "
                        "more for the whole grid",
                        UserWarning,
                        stacklevel=2,
                    )
                if episodes and episodes > n:
                    warnings.warn(
                        f"{name} has {n} episodes (n_offsets x evaluation.repeats = {n}): "
                        f"runs {n}, not the {episodes} asked for (raise evaluation.repeats in the "
                        f"preset for more)",
                        UserWarning,
                        stacklevel=2,
                    )
                cells.append(Cell(name, "invisible", min(n, episodes) if episodes else n, True))
        else:
            for vis in passes:
                cells.append(Cell(name, vis, episodes or ev.episodes, False))
    if not cells:
        raise ConfigError(f"nothing to evaluate: the single-human scenarios ({', '.join(names)}) run with an "
                          f"invisible robot only, and --visibility is {visibility}")
    if ev.split != "train":  # checked before a file is written: the run would die at episode 1000
        for cell in cells:
            if cell.episodes > SPLIT_SIZE:
                why = (f"its offsets x evaluation.repeats {ev.repeats}" if cell.single_human
                       else "--episodes / evaluation.episodes")
                raise ConfigError(f"{cell.scenario}: {cell.episodes} episodes ({why}), more than the "
                                  f"{SPLIT_SIZE} of the {ev.split!r} split; run at most {SPLIT_SIZE}, or "
                                  "evaluation.split: train for more")
    return cells


def preset_for_scenarios(preset: Preset, scenarios: Sequence[str] | None) -> Preset:
    """``preset`` with the scenario lists of a run of ``scenarios`` (None: the preset's own).

    What a policy is checked against (a checkpoint trained without walls is refused where the run
    evaluates scenarios with walls): the scenarios the run evaluates, which ``--scenario`` may take
    from outside the preset's lists. The run's manifest keeps the preset itself.
    """
    if not scenarios:
        return preset
    ev = preset.evaluation
    names = list(dict.fromkeys(scenarios))  # a name given twice is refused by plan_cells, in its words
    single = [s for s in names if s in ev.single_human or _is_single_human(s)]
    multi = [s for s in names if s not in single]
    return dataclasses.replace(preset, evaluation=dataclasses.replace(
        ev, multi_human=tuple(multi), single_human=tuple(single)))


def _is_single_human(name: str) -> bool:
    return name in ("passing", "overtaking", "crossing")


def make_single(preset: Preset, name: str) -> Scenario:
    """Single-human scenario ``name`` as the preset evaluates it (its robot, one human, its repeats)."""
    return make_scenario(name, n_humans=1, robot_v_pref=preset.robot.v_pref, robot_radius=preset.robot.radius,
                         repeats=preset.evaluation.repeats)


def cell_scenario(preset: Preset, cell: Cell) -> Scenario:
    """The scenario a cell evaluates, with the preset's robot and crowd size.

    Single-human cells use :func:`make_single`; scenarios that fix their own crowd keep it.
    """
    if cell.single_human:
        return make_single(preset, cell.scenario)
    # scenarios whose design fixes the crowd (one person head-on, a standing group) keep their own count
    fixed = get_scenario(cell.scenario).fixed_n_humans
    crowd = {} if fixed else {"n_humans": preset.evaluation.n_humans}
    return make_scenario(cell.scenario, **crowd, robot_v_pref=preset.robot.v_pref,
                         robot_radius=preset.robot.radius)


def cell_world_settings(preset: Preset, cell: Cell) -> WorldSettings:
    """The preset's world settings for a cell: its visibility, and M_III's continuation when visible."""
    visible = cell.visibility == "visible"
    return dataclasses.replace(preset.world, visibility=cell.visibility, continue_after_success=visible,
                               continuation_cap=preset.evaluation.continuation_cap)
