"""Several policies into one result directory with one set of tables.

    <out>/policies/<name>/        one protocol run per policy (``run_protocol``'s layout, resumable)
    <out>/summary.json, .csv      every policy's summary rows
    <out>/table2.md/.tex, table3.md/.tex
    <out>/timings.json            per policy: episodes simulated by the last call and its wall time

Each policy's directory is resumed on its own, so an interrupted multi-policy run loses at most the
chunk in progress, and a checkpoint added later is evaluated without re-running the others. A
shipped checkpoint's SHA-256 is recorded in its manifest: a replaced checkpoint is refused in an old
directory instead of being mixed with results of its predecessor.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav._io import DirectoryLock, atomic_write_json, file_sha256
from socialnav.evaluate.report import write_reports
from socialnav.presets import Preset


@dataclass(frozen=True)
class PolicySpec:
    """One policy of a multi-policy run.

    Attributes:
        name: Label in the results (the ``policy`` column; the sub-directory name).
        policy: Registered policy name.
        label: Display name in tables.
        checkpoint: Checkpoint of a learned policy.
        shipped: The checkpoint's index entry, when it ships with the package.
    """

    name: str
    policy: str
    label: str
    checkpoint: Path | None = None
    shipped: dict[str, Any] | None = None


@dataclass(frozen=True)
class MultiResult:
    """The results of evaluating several policies into one directory.

    Attributes:
        out_dir: The result directory.
        summary: One summary row per (policy, scenario, visibility) group.
        timings: Per policy name, ``{"episodes": simulated in this call, "seconds": wall time [s]}``.
        specs: The policies evaluated, in order.
        recorded_timings: Per policy name, what ``timings.json`` records: this call's timing, or the
            earlier call's where this one simulated nothing (a resume).
    """
    out_dir: Path
    summary: list[dict[str, Any]]
    timings: dict[str, dict[str, float]]  # name -> {"episodes": simulated now, "seconds": wall time}
    specs: list[PolicySpec]
    recorded_timings: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)


#: The native policies that plan routes around walls: evaluated by ``--policy all`` only under a preset
#: with walls (on an open floor they act as their plain kinds, rows that would repeat ``orca`` and
#: ``social_force``).
ROUTE_POLICIES = ("orca_route", "social_force_route")


def default_specs(preset_name: str, learned: bool = True, walls: bool = False) -> list[PolicySpec]:
    """Every shipped checkpoint for ``preset_name`` (index order) and the native policies.

    Args:
        preset_name: The preset whose shipped checkpoints to take.
        learned: Include the shipped checkpoints.
        walls: The preset evaluates scenarios with walls: include the route-following natives
            (`ROUTE_POLICIES`).
    """
    from socialnav.policies.building import describe_checkpoint, shipped_checkpoints
    from socialnav.policies.learned_catalog import default_label
    from socialnav.policies.registry import list_policies

    specs = []
    if learned:
        specs += [
            PolicySpec(e.name, e.policy, e.label, e.path, describe_checkpoint(e))
            for e in shipped_checkpoints(preset_name)
        ]
    natives = {"linear": "Linear", "orca": "ORCA", "social_force": "Social force",
               "orca_route": "ORCA + route", "social_force_route": "Social force + route"}
    specs += [
        PolicySpec(p.name, p.name, natives.get(p.name, default_label(p.name)))
        for p in list_policies()
        if not p.learned and (walls or p.name not in ROUTE_POLICIES)
    ]
    names = [s.name for s in specs]
    duplicates = sorted({n for n in names if names.count(n) > 1})
    if duplicates:
        raise ValueError(
            f"two policies would share the result name(s) {duplicates}; fix checkpoints/index.yaml"
        )
    return specs


def run_policies(
    specs: Sequence[PolicySpec],
    preset: Preset,
    out_dir: str | Path,
    *,
    scenarios: Sequence[str] | None = None,
    episodes: int | None = None,
    visibility: str | None = None,
    progress: bool = True,
    batch_size: int = 256,
    workers: int | None = None,
    build: Callable[..., Any] | None = None,
    log: Callable[[str], None] | None = None,
    trajectories: bool = True,
) -> MultiResult:
    """Runs (or resumes) the protocol for every policy of ``specs`` and writes the joint tables.

    ``trajectories=False`` stores no trajectories (as ``run_protocol``'s); the other arguments are
    ``run_protocol``'s, for every policy.

    Raises:
        ResumeMismatchError: A policy's directory holds a different run's results.
    """
    from socialnav.evaluate.manifest import refuse_other_kind
    from socialnav.policies.building import build_policy

    if not specs:
        raise ValueError("no policies to evaluate")
    build = build or build_policy
    out = Path(out_dir)
    refuse_other_kind(out, "several policies")
    out.mkdir(parents=True, exist_ok=True)
    # Each policy's directory has its own lock; this one keeps two calls from writing the shared
    # summary, tables and timings of the same directory at once.
    with DirectoryLock(out, "evaluation of several policies"):
        return _run_policies_locked(specs, preset, out, build, log, dict(
            scenarios=scenarios, episodes=episodes, visibility=visibility, progress=progress,
            batch_size=batch_size, workers=workers, trajectories=trajectories))


def _run_policies_locked(specs: Sequence[PolicySpec], preset: Preset, out: Path, build: Callable[..., Any],
                         log: Callable[[str], None] | None, options: dict[str, Any]) -> MultiResult:
    from socialnav.evaluate.plan import preset_for_scenarios
    from socialnav.evaluate.runner import run_protocol

    scenarios = options["scenarios"]
    summary: list[dict[str, Any]] = []
    timings: dict[str, dict[str, float]] = {}
    kept: dict[str, dict[str, float]] = {}
    # each policy is checked against the scenarios this run evaluates, as `evaluate --policy P` checks it
    # (a checkpoint trained without walls is refused among walls)
    checked_against = preset_for_scenarios(preset, scenarios)
    for spec in specs:
        t0 = time.perf_counter()
        policy = build(spec.policy, checked_against, spec.checkpoint)
        extra = {"checkpoint": str(spec.checkpoint) if spec.checkpoint else None}
        if spec.checkpoint is not None:
            extra["checkpoint_sha256"] = file_sha256(spec.checkpoint)
        if spec.shipped is not None:
            extra["shipped"] = spec.shipped
        result = run_protocol(
            policy,
            preset,
            out / "policies" / spec.name,
            label=spec.name,
            extra_manifest=extra,
            **options,
        )
        seconds = time.perf_counter() - t0
        timings[spec.name] = {"episodes": result.computed_episodes, "seconds": round(seconds, 3)}
        if log is not None:
            log(f"{spec.name}: {result.computed_episodes} episodes simulated in {seconds:.1f} s")
        summary.extend(result.summary)
        kept = _write_timings(out, preset, specs, timings)  # after each policy: an interruption keeps them
    write_reports(out, summary, [], preset)
    return MultiResult(out, summary, timings, list(specs), kept)


def _write_timings(out: Path, preset: Preset, specs: Sequence[PolicySpec],
                   timings: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """Writes ``timings.json`` and returns this call's policies' timings as it records them.

    The file holds this call's timings, the earlier ones where this call simulated nothing (a resume
    would otherwise record 0 episodes in 0 s for the policies an earlier call evaluated), and those of
    the run's policies this call has not reached yet (an interrupted call keeps them).
    """
    import json

    path = out / "timings.json"
    try:
        previous = json.loads(path.read_text()).get("policies", {})
    except (OSError, ValueError, AttributeError):
        previous = {}
    if not isinstance(previous, dict):
        previous = {}
    kept = {}
    for spec in specs:
        before, now = previous.get(spec.name), timings.get(spec.name)
        useful = isinstance(before, dict) and before.get("episodes", 0) > 0
        if now is not None and not (now["episodes"] == 0 and useful):
            kept[spec.name] = now
        elif isinstance(before, dict):
            kept[spec.name] = before
    atomic_write_json(path, {"preset": preset.name, "human_model": preset.world.human_model,
                             "policies": kept})
    return {name: kept[name] for name in timings}


