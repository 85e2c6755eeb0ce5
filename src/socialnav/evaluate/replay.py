"""Re-simulates one stored episode from a result directory's manifest and compares it bit for bit.

The manifest records the preset, the policy (name, parameters, information setting, checkpoint) and
the batch size. Replay rebuilds them and re-simulates the episode's whole chunk up to that episode in
batches of the recorded size: native policies give the same episode in any batch, but a learned
policy evaluates only the active rows, so its floating-point results could depend on which other
episodes share the batch.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.evaluate.results import ResultsError, find_episode, load_episode, load_manifest
from socialnav.policies.registry import RECORDED_ONLY, policy_record
from socialnav.trajectory import Trajectory

_ARRAYS = ("positions", "velocities", "radii", "v_pref", "goals", "min_clearance", "continuation")


@dataclass(frozen=True)
class ReplayResult:
    """The outcome of re-simulating one stored episode.

    Attributes:
        episode_id: The episode replayed.
        stored: Its trajectory as stored in the result directory.
        replayed: Its trajectory simulated again.
        identical: Whether every compared array and the static map are bit-identical.
        max_abs_diff: The largest absolute difference over every compared array and the map's vertices
            (inf when shapes differ, or one of them has a map and the other none).
        differences: One line per field that differs.
    """
    episode_id: str
    stored: Trajectory
    replayed: Trajectory
    identical: bool
    max_abs_diff: float  # over every compared array; inf when shapes differ
    differences: list[str]  # one line per field that differs


def rebuild_policy(manifest: dict[str, Any], preset: Any) -> Any:
    """The policy a manifest describes, built as `socialnav evaluate` built it."""
    from socialnav.policies.building import build_policy
    from socialnav.policies.registry import SB3_PREFIX, get_policy_entry

    desc = dict(manifest.get("policy") or {})
    if manifest.get("policy_entry"):  # a policy of the user's module, whose describe() may name nothing
        return _rebuild_from_module(manifest, desc, preset)
    name = desc.get("policy")
    if not name:
        raise ResultsError("manifest.json: the policy's name (policy.policy) is not recorded")
    try:
        entry = get_policy_entry(name)
    except KeyError as err:
        raise ResultsError(
            f"manifest.json: policy {name!r} is not registered in this installation; {err.args[0]}"
        ) from None
    if name.startswith(SB3_PREFIX):
        return _rebuild_sb3(desc, preset)
    if entry.learned:
        checkpoint = desc.get("checkpoint") or manifest.get("checkpoint")
        if checkpoint and not Path(checkpoint).is_file():
            raise ResultsError(f"manifest.json: the policy's checkpoint {checkpoint} does not exist"
                               + _relative_hint(checkpoint))
        recorded_sha = manifest.get("checkpoint_sha256")
        if checkpoint and recorded_sha:
            from socialnav._io import file_sha256

            if file_sha256(checkpoint) != recorded_sha:  # another network saved at the same path
                raise ResultsError(f"manifest.json: checkpoint {checkpoint} changed since the run (SHA-256 "
                                   f"recorded: {recorded_sha}); replay needs the network the run used")
        # The recorded settings the policy takes (information, planning depth and width, scorer for the
        # value-based ones; deterministic for PPO); the device is not recorded and changes no decision.
        params = {k: desc[k] for k in entry.parameters if k in desc and k != "device"}
        if "scorer" in entry.parameters:  # results written before it was recorded: the PyTorch module
            params["scorer"] = desc.get("scorer", "torch")
        # a run that allowed a preset mismatch recorded it: rebuilt the same way, compared below
        policy = build_policy(name, preset, checkpoint,
                              allow_preset_mismatch=bool(desc.get("preset_mismatch_allowed")), **params)
    else:
        params = {k: desc[k] for k in entry.parameters if k in desc}
        policy = build_policy(name, preset, None, **params)
    rebuilt = {"label": desc.get("label"), **policy_record(policy)}
    if entry.learned and "scorer" not in desc:
        rebuilt.pop("scorer", None)
    for key in RECORDED_ONLY:  # e.g. the native kernel: bit-identical values on any CPU
        rebuilt.pop(key, None)
        desc = {k: v for k, v in desc.items() if k != key}
    if json_norm(rebuilt) != json_norm(desc):
        raise ResultsError(
            f"manifest.json: cannot rebuild the recorded policy {desc}; this installation builds {rebuilt}"
        )
    return policy


def _rebuild_from_module(manifest: dict[str, Any], desc: dict[str, Any], preset: Any) -> Any:
    """A policy of the user's module (``module.path:ClassName``), refused when its source changed."""
    from socialnav.evaluate.manifest import policy_sources
    from socialnav.policies.building import build_policy

    entry = manifest["policy_entry"]
    try:
        policy = build_policy(entry, preset, None, **dict(manifest.get("policy_args") or {}))
    except (KeyError, ImportError, ValueError) as err:
        raise ResultsError(f"manifest.json: cannot build the run's policy {entry} ({err}); replay imports it "
                           "as `socialnav evaluate` did (run it from the same directory)") from None
    recorded = manifest.get("policy_sources") or {}
    if recorded and policy_sources(policy) != recorded:
        raise ResultsError(f"manifest.json: the source of policy {entry} changed since the run (SHA-256 "
                           f"recorded: {recorded}); replay needs the code the run used")
    rebuilt = {"label": desc.get("label"), **policy_record(policy)}
    if json_norm(rebuilt) != json_norm(desc):
        raise ResultsError(
            f"manifest.json: cannot rebuild the recorded policy {desc}; this installation builds {rebuilt}"
        )
    return policy


def _rebuild_sb3(desc: dict[str, Any], preset: Any) -> Any:
    """The SB3 model of the run, refused when its file is gone or changed (SHA-256 differs)."""
    from socialnav.policies.building import build_policy

    model = desc.get("model", "")
    if not Path(model).is_file():
        raise ResultsError(f"manifest.json: the policy's model file {model} does not exist"
                           + _relative_hint(model))
    allow = bool(desc.get("preset_mismatch_allowed"))
    policy = build_policy(
        desc["policy"], preset, None, allow_preset_mismatch=allow, algo=desc.get("algorithm"),
        device=desc.get("device", "cpu"),
    )
    if policy.sha256 != desc.get("sha256"):
        raise ResultsError(
            f"manifest.json: model file {model} changed since the run (SHA-256 {desc.get('sha256')} "
            f"recorded, {policy.sha256} now); replay needs the file the run used"
        )
    rebuilt = {"label": desc.get("label"), **policy_record(policy)}
    if json_norm(rebuilt) != json_norm(desc):
        raise ResultsError(
            f"manifest.json: cannot rebuild the recorded policy {desc}; this installation builds {rebuilt}"
        )
    return policy


def _relative_hint(path: str) -> str:
    """Where a path recorded as typed (relative) is looked for, and how to replay it."""
    if Path(path).is_absolute():
        return ""
    return (f" (looked for from {Path.cwd()}: the run recorded the path as typed, relative to the directory "
            "it was started from; replay from that directory)")


def json_norm(value: Any) -> Any:
    """``value`` as it reads back from JSON (tuples as lists, non-JSON values as strings)."""
    import json

    return json.loads(json.dumps(value, default=str))


def replay_episode(results_dir: str | Path, episode_id: str) -> ReplayResult:
    """Re-simulates ``episode_id`` and compares it with the stored trajectory.

    Raises:
        ResultsError: Not a result directory, unknown episode, or a policy that cannot be rebuilt.
    """
    from socialnav.evaluate.execution import episode_id as make_id
    from socialnav.evaluate.execution import simulate_chunk
    from socialnav.evaluate.plan import Cell, _is_single_human, preset_for_scenarios
    from socialnav.presets import Preset
    from socialnav.settings import ConfigError, from_dict

    root = Path(results_dir)
    manifest = load_manifest(root)
    ref = find_episode(root, episode_id)
    stored = load_episode(root, ref.episode_id)
    try:
        preset = from_dict(Preset, manifest["preset"])
    except (KeyError, ConfigError) as err:
        raise ResultsError(f"{root}/manifest.json: cannot rebuild the preset ({err})") from None
    cells = {(c["scenario"], c["visibility"]): c for c in manifest.get("cells", [])}
    recorded = cells.get((ref.scenario, ref.visibility))
    if recorded is None:
        raise ResultsError(f"{root}/manifest.json: no cell {ref.scenario}/{ref.visibility}")
    single = ref.scenario in preset.evaluation.single_human or _is_single_human(ref.scenario)
    cell = Cell(ref.scenario, ref.visibility, int(recorded["episodes"]), single)
    # built against the run's scenarios, as the run built it (cli: preset_for_scenarios)
    run_scenarios = list(dict.fromkeys(c["scenario"] for c in manifest.get("cells", [])))
    policy = rebuild_policy(manifest, preset_for_scenarios(preset, run_scenarios))
    a, b = ref.chunk
    trajs = simulate_chunk(
        policy,
        preset,
        cell,
        a,
        b,
        manifest["policy"].get("label") or policy.name,
        int(manifest.get("batch_size", 256)),
        until=ref.index,
    )
    replayed = next(t for t in trajs if t.settings["index"] == ref.index)
    replayed.settings["episode"] = make_id(ref.scenario, ref.visibility, ref.index)
    return compare(ref.episode_id, stored, replayed)


def compare(episode_id: str, stored: Trajectory, replayed: Trajectory) -> ReplayResult:
    """Bitwise comparison of every array, the static map, the outcome and the human-overlap count."""
    diffs: list[str] = []
    worst = 0.0
    if stored.dt != replayed.dt:
        diffs.append(f"dt: stored {stored.dt}, replayed {replayed.dt}")
    if stored.outcome != replayed.outcome:
        diffs.append(f"outcome: stored {stored.outcome}, replayed {replayed.outcome}")
    if stored.human_overlaps != replayed.human_overlaps:
        diffs.append(f"human_overlaps: stored {stored.human_overlaps}, replayed {replayed.human_overlaps}")
    for name in _ARRAYS:
        x, y = getattr(stored, name), getattr(replayed, name)
        if x is None and y is None:
            continue
        if x is None or y is None or x.shape != y.shape:
            shape = lambda v: None if v is None else v.shape  # noqa: E731
            diffs.append(f"{name}: stored shape {shape(x)}, replayed shape {shape(y)}")
            worst = float("inf")
            continue
        if not np.array_equal(x, y):
            d = np.abs(x - y)
            at = np.unravel_index(int(np.argmax(d)), d.shape)
            diffs.append(f"{name}: max |difference| {d[at]:.3g} at index {tuple(int(i) for i in at)}")
        if x.size:
            worst = max(worst, float(np.max(np.abs(x - y))))
    line, diff = _compare_maps(stored.static_map, replayed.static_map)
    if line:
        diffs.append(line)
    worst = max(worst, diff)
    return ReplayResult(episode_id, stored, replayed, not diffs, worst, diffs)


def _compare_maps(stored: Any, replayed: Any) -> tuple[str | None, float]:
    """The static maps compared bit for bit, as the arrays are.

    Returns:
        A line naming the map and what differs (None when identical), and the largest absolute vertex
        difference (inf when one has a map and the other none, or the polygons do not match up).
    """

    def describe(smap: Any) -> str:
        return "no map (open floor)" if not smap else f"{len(smap)} polygon(s), {smap.n_vertices} vertices"

    if not stored and not replayed:  # None and an empty map are both the open floor
        return None, 0.0
    if not stored or not replayed or len(stored) != len(replayed):
        return f"static_map: stored {describe(stored)}, replayed {describe(replayed)}", float("inf")
    for p, (a, b) in enumerate(zip(stored.polygons, replayed.polygons, strict=True)):
        if a.shape != b.shape:
            return (f"static_map: polygon {p}: stored {a.shape[0]} vertices, replayed {b.shape[0]}",
                    float("inf"))
    worst, first = 0.0, None
    for p, (a, b) in enumerate(zip(stored.polygons, replayed.polygons, strict=True)):
        if not np.array_equal(a, b):
            d = np.abs(a - b)
            at = np.unravel_index(int(np.argmax(d)), d.shape)
            if first is None:
                first = (f"static_map: polygon {p}, vertex {int(at[0])}: stored {a[at[0]].tolist()}, "
                         f"replayed {b[at[0]].tolist()}")
            worst = max(worst, float(d[at]))
    if first is None:
        return None, 0.0
    return f"{first} (max |difference| {worst:.3g} over the map)", worst
