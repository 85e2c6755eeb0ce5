"""Fixed-seed tiny trainings and the digests of what they write, for the bit-identity test.

``tests/data/train_bit_identical.json`` holds the digests of runs made by the trainer as it was before
it was rewritten as phases (issue #31); ``tests/train/test_trainer_bit_identical.py`` reruns the same
trainings and compares. A digest covers a checkpoint's tensors and records (network, predictor,
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
    from socialnav.train.config import load_train_settings
    from socialnav.train.trainer import train

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
    from socialnav.train.ppo import train_ppo
    from socialnav.train.ppo_config import NetworkSettings, PPOSettings

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


def environment() -> dict[str, str]:
    """What the digests depend on besides the code: torch's version and the machine's architecture."""
    return {"torch": torch.__version__.split("+")[0], "machine": platform.machine()}


def main(argv: list[str] | None = None) -> int:
    """Runs every reference training in a temporary directory and prints (or writes) the digests."""
    import tempfile

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help=f"write {DIGESTS}")
    args = parser.parse_args(argv)
    digests: dict[str, Any] = {"environment": environment(), "runs": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for policy in VALUE_POLICIES:
            train_value(policy, Path(tmp) / policy)
            digests["runs"][policy] = run_digests(Path(tmp) / policy)
        for policy in PPO_POLICIES:
            train_ppo_tiny(policy, Path(tmp) / policy)
            digests["runs"][policy] = run_digests(Path(tmp) / policy)
    text = json.dumps(digests, indent=1, sort_keys=True) + "\n"
    if args.write:
        DIGESTS.write_text(text)
    sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
