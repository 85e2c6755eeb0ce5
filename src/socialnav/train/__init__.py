"""Training of the learned policies: value-based (``train``) and PPO (``train_ppo``).

Value-based training is imitation from ORCA then RL. Needs the ``learn`` extra (PyTorch); see
docs/training.md and docs/ppo.md.

Example::

    from socialnav.train import load_train_settings, train

    result = train("sarl", "wang2022", "runs/sarl", load_train_settings("smoke"))

Each name below loads its module on first use (``TrainSettings`` without importing torch).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "train": "socialnav.train.trainer",
    "TrainResult": "socialnav.train.trainer",
    "TrainSettings": "socialnav.train.config",
    "ImitationSettings": "socialnav.train.config",
    "RLSettings": "socialnav.train.config",
    "load_train_settings": "socialnav.train.config",
    "shipped_train_configs": "socialnav.train.config",
    "train_ppo": "socialnav.train.ppo",
    "PPOResult": "socialnav.train.ppo",
    "PPOSettings": "socialnav.train.ppo_config",
    "load_ppo_settings": "socialnav.train.ppo_config",
    "TrainingDiverged": "socialnav.train.rl",
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
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.train.config import (
        ImitationSettings,
        RLSettings,
        TrainSettings,
        load_train_settings,
        shipped_train_configs,
    )
    from socialnav.train.ppo import PPOResult, train_ppo
    from socialnav.train.ppo_config import PPOSettings, load_ppo_settings
    from socialnav.train.rl import TrainingDiverged
    from socialnav.train.trainer import TrainResult, train
