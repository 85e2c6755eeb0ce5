"""Fixed-seed tiny trainings, the digests of what they write and their numeric summaries.

``tests/data/train_bit_identical.json`` holds, for each run, the digests of the files the trainer
wrote before it was rewritten as phases, and a numeric summary of the same files;
``tests/train/test_trainer_bit_identical.py`` reruns the same trainings and compares: the digests on
the machine and kernels that recorded them (``environment``), the summaries within ``TOLERANCE``
everywhere. A digest covers a checkpoint's tensors and records (network, predictor,
target network, optimizer state, generator states, counters, validations, the worlds in flight), not
its bytes: ``torch.save`` output is not byte-stable. Wall-clock fields (``wall_time``,
``env_steps_per_s``) and the package versions are left out; so is the settings record (``config``),
whose layout another module owns and other tests check. The PPO runs' ``curves.csv`` digests were
regenerated once since, when a window in which no episode ended got empty rates instead of 0 (their
checkpoints' digests did not change).

Regenerate only from a commit whose trainer is known to be right::

    PYTHONPATH=src python -m tests.train.bit_identical_runs --write
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import math
import os
import platform
import sys
from collections.abc import Callable
from importlib import resources
from pathlib import Path
from typing import Any

import torch
import yaml

DIGESTS = Path(__file__).resolve().parents[1] / "data" / "train_bit_identical.json"

#: Value-based settings: every phase (demonstrations, imitation, RL with gradient steps, target
#: updates, validations, best/last checkpoints) in a few seconds.
VALUE_SETTINGS = {
    "collection_batch": 8,
    "threads": 1,
    "checkpoint_every": 8,
    "log_every": 4,
    "imitation": {"episodes": 8, "epochs": 2},
    "rl": {
        "episodes": 24,
        "validate_every": 12,
        "val_episodes": 4,
        "target_update_every": 8,
        "warmup_transitions": 50,
        "gradient_steps_per_episode": 1,
        "epsilon_decay_episodes": 20,
    },
}
#: cadrl (one human), sarl (recomputed targets), rgl (the RGL repository's fixed targets), mp_rgl
#: (learned state predictor and depth-2 planning).
VALUE_POLICIES = ("cadrl", "sarl", "rgl", "mp_rgl")
PPO_POLICIES = ("crowdnav_pp", "ppo_mlp")
CHECKPOINTS = ("il.pt", "best.pt", "last.pt")
#: Non-deterministic or owned elsewhere: left out of the digests.
SKIPPED_KEYS = frozenset({"wall_time", "env_steps_per_s", "torch_version", "socialnav_version", "config"})


def quick_preset(directory: Path) -> str:
    """crowdnav with a 10 s time limit and 3 humans: the ORCA teacher arrives (8 m at 1 m/s), so the
    imitation has demonstrations, and untrained policies time out soon.

    Args:
        directory: where the preset file is written.

    Returns:
        The preset file's path.
    """
    data = yaml.safe_load((resources.files("socialnav.configs") / "crowdnav.yaml").read_text())
    data["name"] = "crowdnav_quick"
    data["world"]["time_limit"] = 10.0
    data["training"]["n_humans"] = 3
    path = directory / "crowdnav_quick.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def train_value(policy: str, out: Path, stop_after: int | None = None) -> None:
    """A tiny value-based training of ``policy`` (seed 0) into ``out``.

    Args:
        policy: a value-based learned policy.
        out: run directory (resumed when it holds last.pt).
        stop_after: RL episodes after which this call stops, as if killed.
    """
    from socialnav.train.value.settings import load_train_settings
    from socialnav.train.value.trainer import train

    out.mkdir(parents=True, exist_ok=True)
    settings_file = out.parent / f"{out.name}-settings.yaml"
    settings_file.write_text(yaml.safe_dump(VALUE_SETTINGS))
    train(
        policy,
        quick_preset(out.parent),
        out,
        load_train_settings(settings_file, seed=0),
        progress=False,
        stop_after=stop_after,
        log=lambda _: None,
    )


def train_ppo_tiny(policy: str, out: Path, stop_after: int | None = None) -> None:
    """A tiny PPO training of ``policy`` under wang2022 (seed 0, small network) into ``out``.

    Args:
        policy: crowdnav_pp or ppo_mlp.
        out: run directory (resumed when it holds last.pt).
        stop_after: updates after which this call stops, as if killed.
    """
    from socialnav.train.ppo.algorithm import train_ppo
    from socialnav.train.ppo.settings import NetworkSettings, PPOSettings

    network = NetworkSettings(
        robot_embed=16, human_hidden=8, attn_size=16, attn_heads=2, human_out=16, rh_attention=8,
        gru_input=8, gru_hidden=16, node_out=16, head_hidden=16,
    )
    settings = PPOSettings(
        policy=policy, n_envs=8, rollout_steps=8, total_env_steps=8 * 8 * 4, epochs=2, minibatches=2,
        validate_every=2, val_episodes=4, checkpoint_every=3, threads=1, network=network, mlp_hidden=16,
        seed=0,
    )
    train_ppo("wang2022", out, settings, progress=False, stop_after=stop_after, log=lambda _: None)


def _canonical(value: Any, update: Callable[[bytes], None]) -> None:
    """Feeds a canonical encoding of ``value`` (nested dicts, lists, tensors, scalars) to ``update``."""
    if isinstance(value, torch.Tensor):
        t = value.detach().cpu().contiguous()
        update(f"T{t.dtype}{tuple(t.shape)}".encode())
        update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
    elif isinstance(value, dict):
        update(b"{")
        for key in sorted(value, key=str):
            if key in SKIPPED_KEYS:
                continue
            update(repr(key).encode())
            _canonical(value[key], update)
        update(b"}")
    elif isinstance(value, (list, tuple)):
        update(b"[")
        for item in value:
            _canonical(item, update)
        update(b"]")
    else:
        update(repr(value).encode())


def checkpoint_digest(path: Path) -> str:
    """SHA-256 of a checkpoint's content (tensors and records, wall-clock fields left out).

    Args:
        path: a checkpoint written by a trainer.

    Returns:
        The hex digest.
    """
    data = torch.load(path, map_location="cpu", weights_only=True)
    h = hashlib.sha256()
    _canonical(data, h.update)
    return h.hexdigest()


def curves_digest(path: Path) -> str:
    """SHA-256 of curves.csv with its wall-clock columns blanked.

    Args:
        path: a run's curves.csv.

    Returns:
        The hex digest.
    """
    with open(path, newline="") as f:
        rows = [{k: ("" if k in SKIPPED_KEYS else v) for k, v in r.items()} for r in csv.DictReader(f)]
    return hashlib.sha256(json.dumps(rows).encode()).hexdigest()


def run_digests(out: Path) -> dict[str, str]:
    """The digests of a finished run directory's checkpoints and curves.

    Args:
        out: the run directory.

    Returns:
        File name → hex digest, for the files the run has.
    """
    found = {name: checkpoint_digest(out / name) for name in CHECKPOINTS if (out / name).exists()}
    found["curves.csv"] = curves_digest(out / "curves.csv")
    return found


#: Variables that select PyTorch's CPU kernels (ATen's vector ISA, MKL's code path, oneDNN's ISA): each
#: changes how a sum is rounded, so a digest holds only under the values it was made with.
KERNEL_VARIABLES = ("ATEN_CPU_CAPABILITY", "MKL_CBWR", "MKL_ENABLE_INSTRUCTIONS", "ONEDNN_MAX_CPU_ISA")


def cpu_model() -> str:
    """The CPU's vendor and model name as /proc/cpuinfo gives them (the machine's name elsewhere)."""
    fields: dict[str, str] = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                key, _, value = line.partition(":")
                fields.setdefault(key.strip(), value.strip())
                if not line.strip():
                    break
    except OSError:
        return platform.processor() or "unknown"
    return f"{fields.get('vendor_id', '?')} {fields.get('model name', '?')}"


def environment() -> dict[str, Any]:
    """What the digests depend on besides the code: torch, the CPU and the kernels torch picks on it.

    MKL and ATen choose their kernels by CPU (the vendor, the model's ISA), and the rounding of a
    float sum follows the kernel: a run on an Intel Xeon gives other digests than the same run on an
    AMD EPYC, and so does one with ``ATEN_CPU_CAPABILITY=avx2`` on the same machine.
    """
    return {
        "torch": torch.__version__.split("+")[0],
        "machine": platform.machine(),
        "cpu": cpu_model(),
        "cpu_capability": torch.backends.cpu.get_cpu_capability(),
        "kernel_variables": {k: os.environ[k] for k in KERNEL_VARIABLES if k in os.environ},
    }


# --- the numeric summary, compared within a tolerance on any machine -------------------------------

#: Relative tolerance of the summaries. Forcing other kernels on the recording machine
#: (ATEN_CPU_CAPABILITY=avx2, MKL_CBWR=COMPATIBLE, ONEDNN_MAX_CPU_ISA=SSE41, alone and together) moved the
#: tiny runs' values by at most 1e-4 of their scale (a PPO loss column; tensors 1e-5 of their norm): 1e-3
#: leaves ten times that for another CPU, while a real change (another draw order, loss, schedule or
#: counter) moves values by far more, or an exact field.
TOLERANCE = 1e-3


def summarize_value(value: Any, prefix: str, out: dict[str, Any]) -> None:
    """Flattens a checkpoint's content into ``out``: per float tensor [numel, sum, L2 norm], per other
    tensor its digest, scalars as they are; wall-clock and owned-elsewhere keys are left out."""
    if isinstance(value, torch.Tensor):
        t = value.detach().cpu()
        if t.dtype.is_floating_point:
            d = t.double()
            out[prefix] = ["float", t.numel(), float(d.sum()), float(d.norm())] if t.numel() else ["float", 0]
        else:
            h = hashlib.sha256()
            _canonical(t, h.update)
            out[prefix] = ["exact", h.hexdigest()]
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            if key not in SKIPPED_KEYS:
                summarize_value(value[key], f"{prefix}/{key}", out)
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            summarize_value(item, f"{prefix}[{i}]", out)
    elif isinstance(value, float):
        out[prefix] = ["scalar", value if math.isfinite(value) else repr(value)]
    else:
        out[prefix] = ["exact", value if isinstance(value, (int, str, bool, type(None))) else repr(value)]


def run_summary(out: Path) -> dict[str, Any]:
    """The numeric summary of a finished run directory: its checkpoints flattened, its curves.

    Args:
        out: the run directory.

    Returns:
        Flattened key → entry for the checkpoints; ``curves.csv`` → its rows without wall-clock columns.
    """
    summary: dict[str, Any] = {}
    for name in CHECKPOINTS:
        if (out / name).exists():
            summarize_value(torch.load(out / name, map_location="cpu", weights_only=True), name, summary)
    with open(out / "curves.csv", newline="") as f:
        summary["curves.csv"] = [
            {k: v for k, v in r.items() if k not in SKIPPED_KEYS} for r in csv.DictReader(f)
        ]
    return summary


def _number(text: str) -> float | None:
    try:
        return float(text)
    except ValueError:
        return None


def _close(a: float, b: float, scale: float) -> bool:
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= TOLERANCE * scale + 1e-9


def compare_summaries(expected: dict[str, Any], actual: dict[str, Any]) -> list[str]:
    """Where ``actual`` leaves ``expected`` beyond rounding, one line each (empty when it does not).

    Integers, strings, random-generator states and other integer tensors must be equal; a float
    tensor's sum and norm must agree within ``TOLERANCE`` of its norm (times sqrt(numel) for the
    sum, whose terms may cancel); a float scalar within ``TOLERANCE`` of its size; a curves column
    within ``TOLERANCE`` of the column's largest magnitude.
    """
    problems = []
    if expected.keys() != actual.keys():
        return [f"keys differ: missing {sorted(expected.keys() - actual.keys())[:5]}, "
                f"new {sorted(actual.keys() - expected.keys())[:5]}"]
    for key in sorted(expected):
        if key == "curves.csv":
            problems += _compare_curves(expected[key], actual[key])
            continue
        e, a = expected[key], actual[key]
        if e[0] != a[0] or e[0] == "exact" or len(e) != len(a):
            if e != a:
                problems.append(f"{key}: {a}, expected {e}")
        elif e[0] == "float" and len(e) == 4:
            norm = max(abs(e[3]), abs(a[3]))
            if e[1] != a[1] or not _close(e[2], a[2], norm * math.sqrt(e[1])) or not _close(e[3], a[3], norm):
                problems.append(f"{key}: [numel, sum, norm] {a[1:]}, expected {e[1:]}")
        elif e[0] == "scalar":
            ev, av = (float(x) for x in (e[1], a[1]))
            if not _close(ev, av, max(abs(ev), abs(av))):
                problems.append(f"{key}: {av!r}, expected {ev!r}")
    return problems


def _compare_curves(expected: list[dict[str, str]], actual: list[dict[str, str]]) -> list[str]:
    if len(expected) != len(actual) or (expected and expected[0].keys() != actual[0].keys()):
        return [f"curves.csv: {len(actual)} rows of {list(actual[0]) if actual else []}, expected "
                f"{len(expected)} rows of {list(expected[0]) if expected else []}"]
    problems = []
    for column in expected[0] if expected else []:
        values = [(_number(e[column]), _number(a[column])) for e, a in zip(expected, actual, strict=True)]
        finite = [abs(v) for pair in values for v in pair if v is not None and math.isfinite(v)]
        scale = max(finite, default=0.0)
        for row, ((ev, av), e, a) in enumerate(zip(values, expected, actual, strict=True)):
            if ev is None or av is None:
                same = e[column] == a[column]
            else:
                same = _close(ev, av, scale)
            if not same:
                problems.append(f"curves.csv row {row} {column}: {a[column]!r}, expected {e[column]!r}")
    return problems


def main(argv: list[str] | None = None) -> int:
    """Runs every reference training in a temporary directory and prints (or writes) the digests."""
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"write {DIGESTS}")
    args = parser.parse_args(argv)
    digests: dict[str, Any] = {"environment": environment(), "runs": {}, "summaries": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for policy in VALUE_POLICIES + PPO_POLICIES:
            train = train_value if policy in VALUE_POLICIES else train_ppo_tiny
            train(policy, Path(tmp) / policy)
            digests["runs"][policy] = run_digests(Path(tmp) / policy)
            digests["summaries"][policy] = run_summary(Path(tmp) / policy)
    text = json.dumps(digests, indent=1, sort_keys=True) + "\n"
    if args.write:
        DIGESTS.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
