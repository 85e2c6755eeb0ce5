"""Each package's public API is its ``__init__``'s ``__all__``: every name resolves, loading costs
nothing until a name is used, and the README and docs import from these APIs."""

from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ["sim", "evaluate", "train", "sweep", "metrics", "policies", "logs", "maps"]
#: What each package exports, at least (what the README and docs use).
EXPECTED = {
    "sim": {"World", "WorldSettings", "Observation", "SocialNavEnv", "SocialNavVectorEnv", "orca_step",
            "ObservationSettings", "LearnerObservation"},
    "evaluate": {"run_protocol", "list_episodes", "load_episode", "replay_episode", "run_policies"},
    "train": {"train", "train_ppo", "TrainSettings", "PPOSettings", "load_train_settings"},
    "sweep": {"load_sweep", "run_sweep", "make_executor"},
    "metrics": {"score_episode", "summarize_rows", "list_metrics"},
    "policies": {"make_policy", "build_policy", "list_policies", "LearnedPolicySpec",
                 "register_learned_policy"},
    "logs": {"score_file", "load_trajectories"},
    "maps": {"StaticMap", "MapError", "load_map", "save_map", "MapFileError", "MAX_COORDINATE"},
}


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_name_resolves(package):
    module = importlib.import_module(f"socialnav.{package}")
    assert EXPECTED[package] <= set(module.__all__)
    assert len(set(module.__all__)) == len(module.__all__), "a name listed twice"
    for name in module.__all__:
        value = getattr(module, name)
        assert value is not None, name
        assert name in dir(module)
    with pytest.raises(AttributeError, match=f"socialnav.{package}' has no attribute 'no_such_name'"):
        module.no_such_name  # noqa: B018


def test_the_light_apis_load_without_torch_and_no_module_before_use():
    code = (
        "import sys\n"
        "import socialnav.sim, socialnav.evaluate, socialnav.train\n"
        "assert 'socialnav.sim.world' not in sys.modules and 'socialnav.evaluate.runner' not in sys.modules\n"
        "from socialnav.sim import World, SocialNavEnv\n"
        "from socialnav.evaluate import run_protocol, list_episodes\n"
        "from socialnav.train import TrainSettings, load_train_settings\n"
        "from socialnav.policies import build_policy, make_policy\n"
        "import socialnav.metrics, socialnav.logs\n"
        "assert 'torch' not in sys.modules, 'torch was imported'\n"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_readme_and_docs_import_the_public_apis():
    private = re.compile(r"from socialnav\.(sim|evaluate|train|sweep|metrics|logs|maps)\.\w+ import")
    for path in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            assert not private.search(line), f"{path.name}:{number} imports a module, not the API: {line}"
