"""The evaluation protocol: plan, run, aggregate and report (see docs/protocol.md).

Example::

    from socialnav.evaluate import run_protocol
    from socialnav.policies import make_policy
    from socialnav.presets import load_preset

    result = run_protocol(make_policy("orca"), load_preset("wang2022"), "results/orca")

Each name below loads its module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "run_protocol": "socialnav.evaluate.runner",
    "ProtocolResult": "socialnav.evaluate.runner",
    "ResumeMismatchError": "socialnav.evaluate.runner",
    "run_policies": "socialnav.evaluate.multi",
    "default_specs": "socialnav.evaluate.multi",
    "PolicySpec": "socialnav.evaluate.multi",
    "MultiResult": "socialnav.evaluate.multi",
    "list_episodes": "socialnav.evaluate.results",
    "load_episode": "socialnav.evaluate.results",
    "load_episode_rows": "socialnav.evaluate.results",
    "load_manifest": "socialnav.evaluate.results",
    "ResultsError": "socialnav.evaluate.results",
    "replay_episode": "socialnav.evaluate.replay",
    "ReplayResult": "socialnav.evaluate.replay",
    "run_reproduction": "socialnav.evaluate.reproduce",
    "write_reproduction": "socialnav.evaluate.reproduce",
    "Reproduction": "socialnav.evaluate.reproduce",
    "render_reports": "socialnav.evaluate.report",
    "write_reports": "socialnav.evaluate.report",
}
__all__ = [
    "run_protocol",
    "ProtocolResult",
    "ResumeMismatchError",
    "run_policies",
    "default_specs",
    "PolicySpec",
    "MultiResult",
    "list_episodes",
    "load_episode",
    "load_episode_rows",
    "load_manifest",
    "ResultsError",
    "replay_episode",
    "ReplayResult",
    "run_reproduction",
    "write_reproduction",
    "Reproduction",
    "render_reports",
    "write_reports",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.evaluate.multi import MultiResult, PolicySpec, default_specs, run_policies
    from socialnav.evaluate.replay import ReplayResult, replay_episode
    from socialnav.evaluate.report import render_reports, write_reports
    from socialnav.evaluate.reproduce import Reproduction, run_reproduction, write_reproduction
    from socialnav.evaluate.results import (
        ResultsError,
        list_episodes,
        load_episode,
        load_episode_rows,
        load_manifest,
    )
    from socialnav.evaluate.runner import ProtocolResult, ResumeMismatchError, run_protocol
