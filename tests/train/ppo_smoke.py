"""The shipped smoke-test PPO schedule (config ``ppo_smoke``), for the PPO tests."""

from __future__ import annotations

import dataclasses
from typing import Any

from socialnav.train.ppo.settings import PPOSettings, load_ppo_settings


def ppo_smoke(**changes: Any) -> PPOSettings:
    """Config ``ppo_smoke`` with ``changes`` (fields of PPOSettings) applied."""
    return dataclasses.replace(load_ppo_settings("ppo_smoke"), **changes)
