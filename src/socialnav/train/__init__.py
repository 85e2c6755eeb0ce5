"""Training of the learned policies, one trainer per algorithm behind one registry.

The trainers that ship: ``value`` (imitation from ORCA, then value-based RL: ``train``) and ``ppo``
(``train_ppo``); a learned policy's record names its trainer, and ``socialnav train``, sweeps and
``socialnav list`` dispatch through the registry (``get_trainer``, ``trainer_for_policy``). Another
trainer is one ``Trainer`` record given to ``register_trainer`` (or an entry point of group
``socialnav.trainers``). Needs the ``learn`` extra (PyTorch); see docs/training.md, docs/ppo.md and
docs/extending.md ("A trainer").

Example::

    from socialnav.train import load_train_settings, train

    result = train("sarl", "wang2022", "runs/sarl", load_train_settings("smoke"))

A trainer of one's own builds on the names after the registry's: the shared run bookkeeping
(``open_run_directory``, ``start_run_files``, ``run_record``, ``derive_seeds``, ``run_device``), the
training worlds (``MultiWorld``) and validation (``validate``, ``better``, ``GreedyActor``). Each name
loads its module on first use (``TrainSettings`` and the registry without importing torch).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "train": "socialnav.train.value.trainer",
    "TrainResult": "socialnav.train.value.trainer",
    "TrainSettings": "socialnav.train.value.settings",
    "ImitationSettings": "socialnav.train.value.settings",
    "RLSettings": "socialnav.train.value.settings",
    "load_train_settings": "socialnav.train.value.settings",
    "shipped_train_configs": "socialnav.train.settings_files",
    "train_ppo": "socialnav.train.ppo.algorithm",
    "PPOResult": "socialnav.train.ppo.algorithm",
    "PPOSettings": "socialnav.train.ppo.settings",
    "load_ppo_settings": "socialnav.train.ppo.settings",
    "TrainingDiverged": "socialnav.train.optim",
    "Trainer": "socialnav.train.registry",
    "register_trainer": "socialnav.train.registry",
    "get_trainer": "socialnav.train.registry",
    "list_trainers": "socialnav.train.registry",
    "trainer_for_policy": "socialnav.train.registry",
    "RunFiles": "socialnav.train.run_directory",
    "derive_seeds": "socialnav.train.run_directory",
    "run_device": "socialnav.train.run_directory",
    "run_record": "socialnav.train.run_directory",
    "open_run_directory": "socialnav.train.run_directory",
    "start_run_files": "socialnav.train.run_directory",
    "flat_diff": "socialnav.train.settings_files",
    "MultiWorld": "socialnav.train.worlds",
    "ppo_policy_config": "socialnav.train.worlds",
    "validate": "socialnav.train.episodes",
    "better": "socialnav.train.episodes",
    "EpisodeStats": "socialnav.train.episodes",
    "GreedyActor": "socialnav.train.episodes",
}
__all__ = [
    "train",
    "TrainResult",
    "TrainSettings",
    "ImitationSettings",
    "RLSettings",
    "load_train_settings",
    "shipped_train_configs",
    "train_ppo",
    "PPOResult",
    "PPOSettings",
    "load_ppo_settings",
    "TrainingDiverged",
    "Trainer",
    "register_trainer",
    "get_trainer",
    "list_trainers",
    "trainer_for_policy",
    "RunFiles",
    "derive_seeds",
    "run_device",
    "run_record",
    "open_run_directory",
    "start_run_files",
    "flat_diff",
    "MultiWorld",
    "ppo_policy_config",
    "validate",
    "better",
    "EpisodeStats",
    "GreedyActor",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.train.episodes import EpisodeStats, GreedyActor, better, validate
    from socialnav.train.optim import TrainingDiverged
    from socialnav.train.ppo.algorithm import PPOResult, train_ppo
    from socialnav.train.ppo.settings import PPOSettings, load_ppo_settings
    from socialnav.train.registry import (
        Trainer,
        get_trainer,
        list_trainers,
        register_trainer,
        trainer_for_policy,
    )
    from socialnav.train.run_directory import (
        RunFiles,
        derive_seeds,
        open_run_directory,
        run_device,
        run_record,
        start_run_files,
    )
    from socialnav.train.settings_files import flat_diff, shipped_train_configs
    from socialnav.train.value.settings import (
        ImitationSettings,
        RLSettings,
        TrainSettings,
        load_train_settings,
    )
    from socialnav.train.value.trainer import TrainResult, train
    from socialnav.train.worlds import MultiWorld, ppo_policy_config
