"""The sweep file: a grid or list of evaluation and training jobs, validated before anything runs.

A sweep file is YAML::

    out: runs/sweep/example          # result directory (``--out`` overrides)
    executor: local                  # local | ray (``--executor`` overrides)
    workers: 2                       # local processes (default: one per core)
    retries: 3                       # how often a chunk whose worker died is run again
    defaults:                        # applied to every job whose kind takes the key
      preset: wang2022
      episodes: 50
    grid:                            # one mapping, or a list of them; lists are axes of a product
      - kind: evaluate
        policy: [linear, orca, social_force]
        human_model: [orca, social_force]
      - kind: train
        policy: sarl
        seed: [0, 1, 2]
    jobs:                            # single jobs, added to the grid's
      - kind: evaluate
        policy: sarl
        checkpoint: "train:sarl-s{seed}"   # best.pt of this sweep's training job of that name
        seed: [0, 1, 2]

Every job gets a name (``name:``, a template over the job's keys such as ``"{policy}-s{seed}"``, or
one made of its policy and the values of its grid axes) that is its directory under ``out``. Every
problem (unknown key, policy, preset, scenario, human model, a checkpoint that does not exist, two
jobs of one name) is refused before any job starts, naming the entry.
"""

from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from socialnav.config import ConfigError

KINDS = ("evaluate", "train")
EXECUTORS = ("local", "ray")

#: Keys of an evaluation job and what each means (docs/sweeps.md).
EVALUATE_KEYS = {
    "kind",
    "name",
    "policy",
    "checkpoint",
    "preset",
    "scenarios",
    "episodes",
    "visibility",
    "human_model",
    "information",
    "planning_depth",
    "planning_width",
    "policy_args",
    "batch_size",
    "trajectories",
    "seed",
    "allow_preset_mismatch",
}
#: Keys of a training job (those of ``socialnav train``).
TRAIN_KEYS = {
    "kind",
    "name",
    "policy",
    "preset",
    "seed",
    "config",
    "device",
    "information",
    "rl_episodes",
    "collection_batch",
    "human_model",
}
TOP_KEYS = {"out", "executor", "workers", "retries", "address", "threads", "defaults", "grid", "jobs"}
TRAIN_REFERENCE = "train:"
_NAME_OK = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.=+-]*$")


@dataclass(frozen=True)
class Job:
    """One job of a sweep: ``kind`` is evaluate or train; ``params`` its keys (less kind and name)."""

    kind: str
    name: str
    params: dict[str, Any]
    where: str  # the entry of the sweep file it comes from, for messages

    def get(self, key: str, default: Any = None) -> Any:
        return self.params.get(key, default)


@dataclass(frozen=True)
class SweepSpec:
    jobs: list[Job]
    out: str | None = None
    executor: str = "local"
    workers: int | None = None
    retries: int = 3
    address: str | None = None
    threads: int = 1
    source: str = "<sweep>"
    raw: dict[str, Any] = field(default_factory=dict)

    @property
    def train_jobs(self) -> list[Job]:
        return [j for j in self.jobs if j.kind == "train"]

    @property
    def evaluate_jobs(self) -> list[Job]:
        return [j for j in self.jobs if j.kind == "evaluate"]


def load_sweep(path: str | Path) -> SweepSpec:
    """Reads and validates a sweep file (see the module docstring).

    Raises:
        ConfigError: the file, the entry and the problem are named.
    """
    import yaml

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"sweep file {path}: " + ("is a directory" if path.is_dir() else "does not exist"))
    try:
        data = yaml.safe_load(path.read_text())
    except UnicodeDecodeError:
        raise ConfigError(f"sweep file {path}: not a text (YAML) file") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"sweep file {path}: not valid YAML: {' '.join(str(err).split())}") from None
    return parse_sweep(data, source=str(path), base=path.parent)


def parse_sweep(data: Any, source: str = "<sweep>", base: Path | None = None) -> SweepSpec:
    """Validates a sweep given as a mapping (the parsed YAML); relative checkpoint and config paths are
    taken relative to ``base`` when they exist there, else to the working directory."""
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping with grid: and/or jobs:, got {type(data).__name__}")
    unknown = sorted(set(data) - TOP_KEYS)
    if unknown:
        raise ConfigError(f"{source}: unknown key(s) {unknown}; valid: {sorted(TOP_KEYS)}")
    defaults = data.get("defaults") or {}
    if not isinstance(defaults, dict):
        raise ConfigError(f"{source}: defaults must be a mapping, got {type(defaults).__name__}")
    bad = sorted(set(defaults) - (EVALUATE_KEYS | TRAIN_KEYS) | ({"kind", "name"} & set(defaults)))
    if bad:
        raise ConfigError(f"{source}: defaults: key(s) {bad} are not job settings")
    entries: list[tuple[str, dict[str, Any], list[str]]] = []
    grids = data.get("grid") or []
    grids = [grids] if isinstance(grids, dict) else grids
    if not isinstance(grids, list):
        raise ConfigError(f"{source}: grid must be a mapping or a list of mappings")
    for i, grid in enumerate(grids):
        entries.extend(_expand(grid, f"{source}: grid[{i}]"))
    jobs_raw = data.get("jobs") or []
    if not isinstance(jobs_raw, list):
        raise ConfigError(f"{source}: jobs must be a list of mappings")
    for i, job in enumerate(jobs_raw):
        entries.extend(_expand(job, f"{source}: jobs[{i}]"))
    if not entries:
        raise ConfigError(f"{source}: no jobs (give grid: and/or jobs:)")
    jobs = [_make_job(params, axes, where, defaults, base) for where, params, axes in entries]
    names: dict[tuple[str, str], str] = {}
    for job in jobs:
        key = (job.kind, job.name)
        if key in names:
            raise ConfigError(
                f"{job.where}: job name {job.name!r} is also the name of {names[key]}; "
                "give the jobs distinct name: templates"
            )
        names[key] = job.where
    spec = SweepSpec(
        jobs=jobs,
        out=_opt(data, "out", str, source),
        executor=_choice(data.get("executor", "local"), EXECUTORS, f"{source}: executor"),
        workers=_positive(data.get("workers"), f"{source}: workers"),
        retries=_count(data.get("retries", 3), f"{source}: retries"),
        address=_opt(data, "address", str, source),
        threads=_positive(data.get("threads", 1), f"{source}: threads") or 1,
        source=source,
        raw=data,
    )
    _check_references(spec)
    return spec


def _expand(entry: Any, where: str) -> list[tuple[str, dict[str, Any], list[str]]]:
    """A grid entry's cartesian product (list values are axes; a ``scenarios`` list is one value)."""
    if not isinstance(entry, dict):
        raise ConfigError(f"{where}: expected a mapping, got {type(entry).__name__}")
    axes = [k for k, v in entry.items() if isinstance(v, list) and k not in ("scenarios",)]
    for k in axes:
        if not entry[k]:
            raise ConfigError(f"{where}: {k} is an empty list")
    out = []
    for combo in itertools.product(*(entry[k] for k in axes)):
        params = {**entry, **dict(zip(axes, combo, strict=True))}
        label = (
            where
            if not axes
            else where + "{" + ", ".join(f"{k}={v}" for k, v in zip(axes, combo, strict=True)) + "}"
        )
        out.append((label, params, axes))
    return out


def _make_job(params: dict[str, Any], axes: list[str], where: str, defaults: dict, base: Path | None) -> Job:
    kind = params.get("kind")
    if kind not in KINDS:
        raise ConfigError(f"{where}: kind must be one of {', '.join(KINDS)}, got {kind!r}")
    valid = EVALUATE_KEYS if kind == "evaluate" else TRAIN_KEYS
    unknown = sorted(set(params) - valid)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {unknown} for a {kind} job; valid: {sorted(valid)}")
    merged = {k: v for k, v in defaults.items() if k in valid}
    merged.update({k: v for k, v in params.items() if k not in ("kind", "name")})
    if "policy" not in merged:
        raise ConfigError(f"{where}: a {kind} job needs policy:")
    merged.setdefault("preset", "wang2022")
    if kind == "train":
        merged.setdefault("seed", 0)
    name_template = params.get("name")
    context = {k: v for k, v in merged.items() if isinstance(v, (str, int, float, bool))}
    merged = {k: (_fill(v, context, where, k) if k == "checkpoint" else v) for k, v in merged.items()}
    if name_template is not None:
        name = _fill(str(name_template), context, where, "name")
    else:
        parts = [str(merged["policy"]).rpartition(":")[2]]
        parts += [f"{k}={merged[k]}" for k in axes if k not in ("policy", "kind")]
        if kind == "train" and "seed" not in axes:
            parts.append(f"seed={merged['seed']}")
        name = "-".join(parts)
    name = name.replace("/", "_")
    if not _NAME_OK.match(name):
        raise ConfigError(f"{where}: job name {name!r} may hold only letters, digits and _ . = + -")
    _check_job(kind, merged, where, base)
    return Job(kind, name, merged, where)


def _fill(value: Any, context: dict[str, Any], where: str, key: str) -> Any:
    if not isinstance(value, str) or "{" not in value:
        return value
    try:
        return value.format(**context)
    except (KeyError, IndexError, ValueError) as err:
        raise ConfigError(f"{where}: {key} template {value!r} names no key of the job ({err})") from None


def _check_job(kind: str, params: dict[str, Any], where: str, base: Path | None) -> None:
    """Everything that can be checked without running: names, presets, files, types."""
    from socialnav.policies.base import get_policy_entry
    from socialnav.presets import load_preset
    from socialnav.scenarios import get_scenario
    from socialnav.sim.settings import HUMAN_MODELS

    params["preset"] = _path_or_name(params["preset"], base)
    try:
        entry = get_policy_entry(str(params["policy"]))
        preset = load_preset(params["preset"])
        for scenario in params.get("scenarios") or []:
            get_scenario(scenario)
    except (KeyError, ValueError, ConfigError) as err:
        raise ConfigError(f"{where}: {err.args[0] if err.args else err}") from None
    if params.get("human_model") is not None:
        _choice(params["human_model"], HUMAN_MODELS, f"{where}: human_model")
    if kind == "train":
        if not entry.learned:
            raise ConfigError(
                f"{where}: policy {params['policy']!r} does not learn; train takes cadrl, "
                "lstm_rl, sarl, om_sarl, rgl or mp_rgl"
            )
        for key in ("seed", "rl_episodes", "collection_batch"):
            if params.get(key) is not None and (not isinstance(params[key], int) or params[key] < 0):
                raise ConfigError(f"{where}: {key} must be a whole number >= 0, got {params[key]!r}")
        if params.get("config") is not None:
            from socialnav.train.config import load_train_settings

            params["config"] = _path_or_name(params["config"], base)
            try:
                load_train_settings(params["config"])
            except ConfigError as err:
                raise ConfigError(f"{where}: config: {err}") from None
        return
    for key in ("episodes", "batch_size", "planning_depth", "planning_width"):
        if params.get(key) is not None and (not isinstance(params[key], int) or params[key] < 1):
            raise ConfigError(f"{where}: {key} must be a whole number >= 1, got {params[key]!r}")
    if params.get("scenarios") is not None and not isinstance(params["scenarios"], list):
        raise ConfigError(f"{where}: scenarios must be a list of scenario names")
    if params.get("policy_args") is not None and not isinstance(params["policy_args"], dict):
        raise ConfigError(f"{where}: policy_args must be a mapping of parameter: value")
    if params.get("visibility") is not None:
        _choice(params["visibility"], ("invisible", "visible", "both"), f"{where}: visibility")
    checkpoint = params.get("checkpoint")
    if checkpoint is not None:
        if not entry.learned:
            raise ConfigError(f"{where}: policy {params['policy']!r} is not learned and takes no checkpoint")
        if not str(checkpoint).startswith(TRAIN_REFERENCE):
            resolved = Path(_path_or_name(str(checkpoint), base))
            if not resolved.is_file():
                raise ConfigError(f"{where}: checkpoint {checkpoint} does not exist")
            params["checkpoint"] = str(resolved)
    elif entry.learned:
        from socialnav.policies.loading import shipped_checkpoint

        if shipped_checkpoint(str(params["policy"]), preset.name) is None:
            raise ConfigError(
                f"{where}: policy {params['policy']!r} is learned and no checkpoint of it ships "
                f"for preset {preset.name!r}: give checkpoint: (a file or train:<job name>)"
            )


def _check_references(spec: SweepSpec) -> None:
    trained = {j.name for j in spec.train_jobs}
    for job in spec.evaluate_jobs:
        checkpoint = str(job.get("checkpoint") or "")
        if checkpoint.startswith(TRAIN_REFERENCE) and checkpoint[len(TRAIN_REFERENCE) :] not in trained:
            raise ConfigError(
                f"{job.where}: checkpoint {checkpoint!r} names no training job of this sweep "
                f"(training jobs: {', '.join(sorted(trained)) or 'none'})"
            )


def _path_or_name(value: Any, base: Path | None) -> str:
    """A file path relative to the sweep file where it exists there, else the value as given."""
    text = str(value)
    if base is not None and not Path(text).is_absolute() and (base / text).exists():
        return str(base / text)
    return text


def _choice(value: Any, valid: tuple[str, ...] | list[str], where: str) -> str:
    if value not in valid:
        raise ConfigError(f"{where} must be one of {', '.join(valid)}, got {value!r}")
    return value


def _positive(value: Any, where: str) -> int | None:
    if value is None:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or value < 1:
        raise ConfigError(f"{where} must be a whole number >= 1, got {value!r}")
    return value


def _count(value: Any, where: str) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise ConfigError(f"{where} must be a whole number >= 0, got {value!r}")
    return value


def _opt(data: dict, key: str, typ: type, source: str) -> Any:
    value = data.get(key)
    if value is not None and not isinstance(value, typ):
        raise ConfigError(f"{source}: {key} must be a {typ.__name__}, got {value!r}")
    return value


def job_record(job: Job) -> dict[str, Any]:
    """A job as written to ``sweep.json``."""
    return {"kind": job.kind, "name": job.name, **job.params}
