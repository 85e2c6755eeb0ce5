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

import dataclasses
import difflib
import itertools
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from socialnav._io import load_yaml
from socialnav.settings import ConfigError, Settings, setting
from socialnav.sim.settings import HUMAN_MODELS
from socialnav.train.settings_files import DEVICES
from socialnav.train.value.settings import INFORMATION

KINDS = ("evaluate", "train")
EXECUTORS = ("local", "ray")
TRAIN_REFERENCE = "train:"
_NAME_OK = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.=+-]*$")


@dataclass(frozen=True)
class SweepSettings(Settings):
    """The top level of a sweep file (its jobs are `EvaluateJobSettings` and `TrainJobSettings`)."""

    out: str | None = setting(None, "result directory (--out overrides; default runs/sweep/<file name>)")
    executor: str = setting("local", "where the tasks run (--executor overrides)", choices=EXECUTORS)
    workers: int | None = setting(
        None, "local processes / CPUs of a Ray instance started here (default: one per core)", ge=1
    )
    retries: int = setting(3, "how often a task whose worker died while it ran alone is run again", ge=0)
    address: str | None = setting(None, "an existing Ray cluster's address (HEAD_IP:6379)")
    threads: int = setting(1, "torch and native threads per worker", ge=1)
    defaults: dict[str, Any] = setting(
        default_factory=dict, doc="keys applied to every job whose kind takes them"
    )
    grid: dict[str, Any] | list[Any] | None = setting(
        None, "one job mapping or a list of them; list values are the axes of a product"
    )
    jobs: list[Any] | None = setting(None, "single jobs (a list value is an axis here too)")


@dataclass(frozen=True)
class EvaluateJobSettings(Settings):
    """The keys of an evaluation job (those of ``socialnav evaluate``); None: the command's default."""

    policy: str | None = setting(None, "a registered name, an entry point, or module.path:Class (required)")
    checkpoint: str | None = setting(None, "a checkpoint file, or train:<job name> (best.pt of that job)")
    preset: str | None = setting(None, "preset name or YAML file (default wang2022)")
    scenarios: tuple[str, ...] | None = setting(None, "scenario names (a list: one value, not an axis)")
    episodes: int | None = setting(None, "episodes per scenario", ge=1)
    visibility: str | None = setting(None, "the humans' visibility", choices=("invisible", "visible", "both"))
    human_model: str | None = setting(
        None, "the humans' model (overrides the preset's)", choices=HUMAN_MODELS
    )
    information: str | None = setting(
        None, "how a learned policy's lookahead predicts the humans (default: the checkpoint's)",
        choices=INFORMATION,
    )
    planning_depth: int | None = setting(None, "model-predictive planning depth", ge=1)
    planning_width: int | None = setting(None, "model-predictive planning width", ge=1)
    policy_args: dict[str, Any] | None = setting(None, "policy parameters (as --policy-arg)")
    batch_size: int | None = setting(None, "episodes simulated together", ge=1)
    trajectories: bool | None = setting(None, "store the trajectories (default true)")
    seed: int | None = setting(None, "only a value for name templates (the protocol's episodes are fixed)")
    allow_preset_mismatch: bool | None = setting(None, "evaluate a checkpoint in another preset's world")


@dataclass(frozen=True)
class TrainJobSettings(Settings):
    """The keys of a training job (those of ``socialnav train``); None: the command's default."""

    policy: str | None = setting(None, "a learned policy to train (required)")
    preset: str | None = setting(None, "preset name or YAML file (default wang2022)")
    seed: int | None = setting(None, "master seed (default 0)", ge=0)
    config: str | None = setting(None, "training settings: a YAML file or a shipped config name (smoke)")
    device: str | None = setting(None, "torch device", choices=DEVICES)
    information: str | None = setting(None, "the lookahead's prediction", choices=INFORMATION)
    rl_episodes: int | None = setting(None, "RL episodes (trainers taking --rl-episodes: value-based)", ge=0)
    env_steps: int | None = setting(None, "environment steps in all (trainers taking --env-steps: PPO)", ge=1)
    collection_batch: int | None = setting(
        None, "episodes stepped in lockstep while collecting (PPO: environments, n_envs)", ge=1
    )
    human_model: str | None = setting(
        None, "the humans' model (overrides the preset's)", choices=HUMAN_MODELS
    )


#: Keys of an evaluation job and what each means (docs/sweeps.md).
EVALUATE_KEYS = {"kind", "name", *(f.name for f in dataclasses.fields(EvaluateJobSettings))}
#: Keys of a training job (those of ``socialnav train``).
TRAIN_KEYS = {"kind", "name", *(f.name for f in dataclasses.fields(TrainJobSettings))}
TOP_KEYS = {f.name for f in dataclasses.fields(SweepSettings)}
_JOB_SETTINGS: dict[str, type[Settings]] = {"evaluate": EvaluateJobSettings, "train": TrainJobSettings}


@dataclass(frozen=True)
class Job:
    """One job of a sweep: ``kind`` is evaluate or train; ``params`` its keys (less kind and name)."""

    kind: str
    name: str
    params: dict[str, Any]
    where: str  # the entry of the sweep file it comes from, for messages

    def get(self, key: str, default: Any = None) -> Any:
        """The job's value of ``key``, or ``default`` when the job does not set it."""
        return self.params.get(key, default)


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: its jobs and the top-level settings (see `SweepSettings`).

    Attributes:
        jobs: Every job, the grids' expanded.
        out, executor, workers, retries, address, threads: As in `SweepSettings`.
        source: The sweep file (for messages).
        raw: The parsed YAML as given.
    """

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
        """The training jobs, in file order."""
        return [j for j in self.jobs if j.kind == "train"]

    @property
    def evaluate_jobs(self) -> list[Job]:
        """The evaluation jobs, in file order."""
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
        data = load_yaml(path.read_text())
    except UnicodeDecodeError:
        raise ConfigError(f"sweep file {path}: not a text (YAML) file") from None
    except yaml.YAMLError as err:
        raise ConfigError(f"sweep file {path}: not valid YAML: {' '.join(str(err).split())}") from None
    return parse_sweep(data, source=str(path), base=path.parent)


def parse_sweep(data: Any, source: str = "<sweep>", base: Path | None = None) -> SweepSpec:
    """Validates a sweep given as a mapping (the parsed YAML).

    Args:
        data: The parsed sweep file.
        source: Its name in messages.
        base: Relative checkpoint and config paths are taken relative to it when they exist there,
            else to the working directory.

    Returns:
        The validated sweep.

    Raises:
        ConfigError: The file, the entry and the problem are named.
    """
    if not isinstance(data, dict):
        raise ConfigError(f"{source}: expected a mapping with grid: and/or jobs:, got {type(data).__name__}")
    top = SweepSettings.from_dict({k: v for k, v in data.items() if v is not None}, source=source)
    defaults = top.defaults
    for key in sorted(defaults, key=str):
        if key in ("kind", "name") or key not in EVALUATE_KEYS | TRAIN_KEYS:
            close = difflib.get_close_matches(str(key), sorted(EVALUATE_KEYS | TRAIN_KEYS - {"kind", "name"}),
                                              n=1)
            hint = f" (did you mean {close[0]}?)" if close else ""
            raise ConfigError(f"{source}: defaults: {key!r} is not a job setting{hint}")
    entries: list[tuple[str, dict[str, Any], list[str]]] = []
    grids = top.grid or []
    grids = [grids] if isinstance(grids, dict) else grids  # each entry is checked by _expand
    for i, grid in enumerate(grids):
        entries.extend(_expand(grid, f"{source}: grid[{i}]"))
    for i, job in enumerate(top.jobs or []):
        entries.extend(_expand(job, f"{source}: jobs[{i}]"))
    if not entries:
        raise ConfigError(f"{source}: no jobs (give grid: and/or jobs:)")
    jobs = [_make_job(params, axes, where, defaults, base) for where, params, axes in entries]
    names: dict[tuple[str, str], str] = {}
    for job in jobs:
        key = (job.kind, job.name)
        if key in names:
            other = ("another job of the same entry (an axis lists a value twice?)" if names[key] == job.where
                     else names[key])
            raise ConfigError(
                f"{job.where}: job name {job.name!r} is also the name of {other}; "
                "give the jobs distinct name: templates"
            )
        names[key] = job.where
    spec = SweepSpec(
        jobs=jobs,
        out=top.out,
        executor=top.executor,
        workers=top.workers,
        retries=top.retries,
        address=top.address,
        threads=top.threads,
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
    merged = {k: v for k, v in defaults.items() if k in valid}
    merged.update({k: v for k, v in params.items() if k not in ("kind", "name")})
    # the keys, types and ranges, declared once by the job's settings class
    _JOB_SETTINGS[kind].from_dict(merged, source=where)
    if "policy" not in merged:
        raise ConfigError(f"{where}: {'an' if kind[0] in 'aeiou' else 'a'} {kind} job needs policy:")
    merged.setdefault("preset", "wang2022")
    if kind == "train":
        merged.setdefault("seed", 0)
    name_template = params.get("name")
    context = {k: v for k, v in merged.items() if isinstance(v, (str, int, float, bool))}
    merged = {k: (_fill(v, context, where, k) if k == "checkpoint" else v) for k, v in merged.items()}
    if name_template is not None:
        name = _fill(str(name_template), context, where, "name", merged)
    else:
        parts = [str(merged["policy"]).rpartition(":")[2]]
        parts += [f"{k}={merged[k]}" for k in axes if k not in ("policy", "kind")]
        if kind == "train" and "seed" not in axes:
            parts.append(f"seed={merged['seed']}")
        name = "-".join(parts)
    written, name = name, name.replace("/", "_")  # a preset file on an axis names a directory
    if not _NAME_OK.match(name):
        shown = repr(written) if written == name else f"{written!r} (as a directory: {name!r})"
        raise ConfigError(f"{where}: job name {shown} may hold only letters, digits and _ . = + -")
    _check_job(kind, merged, where, base)
    return Job(kind, name, merged, where)


def _fill(value: Any, context: dict[str, Any], where: str, key: str,
          job: dict[str, Any] | None = None) -> Any:
    if not isinstance(value, str) or "{" not in value:
        return value
    try:
        return value.format(**context)
    except KeyError as err:
        missing = err.args[0] if err.args else ""
        if job is not None and missing in job:
            raise ConfigError(f"{where}: {key} template {value!r}: {missing} is a list or mapping, which a "
                              "name cannot hold; use scalar keys (policy, seed, preset, …)") from None
        raise ConfigError(f"{where}: {key} template {value!r} names no key of the job ({err})") from None
    except (IndexError, ValueError) as err:
        raise ConfigError(f"{where}: {key} template {value!r} names no key of the job ({err})") from None


def _check_train_job(entry: Any, params: dict[str, Any], where: str, base: Path | None) -> None:
    """A training job: a learned policy, its trainer's settings (as ``socialnav train`` checks them)."""
    from socialnav.policies.learned_catalog import learned_policy_names
    from socialnav.train.registry import OPTIONS, trainer_for_policy

    if not entry.learned or str(params["policy"]) not in learned_policy_names():
        raise ConfigError(f"{where}: policy {params['policy']!r} does not learn; train takes "
                          f"{', '.join(learned_policy_names())}")
    try:
        trainer = trainer_for_policy(str(params["policy"]))
    except ConfigError as err:
        raise ConfigError(f"{where}: {err}") from None
    given = [k for k in OPTIONS if params.get(k) is not None and k not in trainer.options]
    if given:
        raise ConfigError(f"{where}: {trainer.refuse_options(given, str(params['policy']), flags=False)}")
    if params.get("config") is not None:
        params["config"] = _path_or_name(params["config"], base)
    try:
        trainer.load_settings(params.get("config"), policy=str(params["policy"]))
    except ConfigError as err:
        raise ConfigError(f"{where}: config: {err}") from None


def _check_job(kind: str, params: dict[str, Any], where: str, base: Path | None) -> None:
    """What the settings classes cannot check without running: policies, presets, scenarios, files."""
    from socialnav.policies.registry import get_policy_entry
    from socialnav.presets import load_preset
    from socialnav.scenarios import get_scenario

    params["preset"] = _path_or_name(params["preset"], base)
    scenarios = params.get("scenarios")
    if scenarios is not None and len(scenarios) == 0:
        raise ConfigError(f"{where}: scenarios is an empty list; leave the key out to run the preset's "
                          "scenarios")
    repeated = sorted({s for s in scenarios or () if list(scenarios).count(s) > 1})
    if repeated:
        raise ConfigError(f"{where}: scenarios: {', '.join(repeated)} given more than once")
    if kind == "train":  # a trainer's plugin may be what registers the policy it trains
        from socialnav.train.registry import load_trainer_plugins

        load_trainer_plugins()
    try:
        entry = get_policy_entry(str(params["policy"]))
        preset = load_preset(params["preset"])
        for scenario in scenarios or []:
            get_scenario(scenario)
    except (KeyError, ValueError, ConfigError) as err:
        raise ConfigError(f"{where}: {err.args[0] if err.args else err}") from None
    if kind == "train":
        _check_train_job(entry, params, where, base)
        return
    from socialnav.policies.building import LOOKAHEAD_SETTINGS, refuse_lookahead_setting

    name = str(params["policy"])
    try:
        for key in LOOKAHEAD_SETTINGS:
            if params.get(key) is not None:
                refuse_lookahead_setting(name, key, key)
    except ValueError as err:
        raise ConfigError(f"{where}: {err}") from None
    _check_policy_args(where, name, entry, params)
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
        from socialnav.policies.building import shipped_checkpoint

        if shipped_checkpoint(str(params["policy"]), preset.name) is None:
            raise ConfigError(
                f"{where}: policy {params['policy']!r} is learned and no checkpoint of it ships "
                f"for preset {preset.name!r}: give checkpoint: (a file or train:<job name>)"
            )


def _check_policy_args(where: str, name: str, entry: Any, params: dict[str, Any]) -> None:
    """Refuse a job's ``policy_args`` that its policy does not have, naming the sweep file, not at run time.

    A device is checked where the job runs (a Ray worker may have the GPU the driver lacks).
    """
    from socialnav.policies.building import check_policy_parameters
    from socialnav.policies.registry import SB3_PREFIX

    args = dict(params.get("policy_args") or {})
    if not args or name.startswith(SB3_PREFIX) or ":" in name:
        return  # an SB3 model or a user's class checks its own arguments when built
    try:
        check_policy_parameters(name, entry, args, check_device=False)
    except ValueError as err:
        raise ConfigError(f"{where}: policy_args: {err}") from None


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


def job_record(job: Job) -> dict[str, Any]:
    """A job as written to ``sweep.json``."""
    return {"kind": job.kind, "name": job.name, **job.params}
