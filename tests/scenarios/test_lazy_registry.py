"""``socialnav.scenarios`` imports no built-in scenario module; the registry loads them on first use.

Each test runs in a fresh interpreter: what matters is which modules an import loads, and this
test process has loaded every scenario module long ago.
"""

from __future__ import annotations

import ast
import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[2] / "docs" / "scenarios.md"
BUILTIN_MODULES = ("circle", "francis", "single", "square", "walls")

#: Asserts that no built-in scenario module is loaded yet (prepended to the snippets below).
NOTHING_LOADED = (
    "import sys\n"
    "import socialnav.scenarios\n"
    f"loaded = [m for m in {list(BUILTIN_MODULES)!r} if 'socialnav.scenarios.' + m in sys.modules]\n"
    "assert not loaded, f'imported eagerly: {loaded}'\n"
)


def run_fresh(code: str) -> str:
    """Runs ``code`` in a new interpreter and returns its stdout; fails the test on an error."""
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    return result.stdout


def documented_builtins() -> set[str]:
    """The scenario names docs/scenarios.md documents: its tables' rows and the walled list."""
    text = DOCS.read_text(encoding="utf-8")
    sections = dict(re.findall(r"^## (.+?)\n(.*?)(?=^## |\Z)", text, flags=re.M | re.S))
    names = set()
    for title in ("Multi-human scenarios", "Single-human scenarios (side preference, M_VI)"):
        names |= set(re.findall(r"^\| `(\w+)` \|", sections[title], flags=re.M))
    walled = sections["Scenarios with walls"].strip().split("\n\n")[0]  # the paragraph listing them
    names |= set(re.findall(r"`(\w+)`", walled.split("(Francis")[0]))
    return names


def test_the_docs_list_the_builtins_this_test_expects():
    # guards the parsing below: 5 multi-human, 3 single-human, 9 with walls
    names = documented_builtins()
    assert len(names) == 17
    assert {"circle_crossing", "crossing", "narrow_doorway", "circle_crossing_obstacles"} <= names


def test_make_scenario_works_with_nothing_else_imported():
    out = run_fresh(
        NOTHING_LOADED + "from socialnav.scenarios import make_scenario\n"
        "batch = make_scenario('circle_crossing', n_humans=3).episodes('test', [0, 1])\n"
        "print(batch.human_start.shape)\n"
    )
    assert out.strip() == "(2, 3, 2)"


def test_list_scenarios_lists_every_documented_builtin():
    out = run_fresh(
        NOTHING_LOADED + "from socialnav.scenarios import list_scenarios\n"
        "print(' '.join(list_scenarios()))\n"
    )
    listed = set(out.split())
    assert documented_builtins() <= listed


def test_every_lookup_loads_the_builtins():
    # each entry point of the registry, called first in a fresh interpreter, sees the built-ins
    calls = {
        "get_scenario": "get_scenario('narrow_doorway')",
        "make_scenario": "make_scenario('passing')",
        "scenario_from_settings": "scenario_from_settings({'type': 'square_crossing'})",
        "list_scenarios": "list_scenarios()['intersection']",
    }
    for name, call in calls.items():
        out = run_fresh(
            NOTHING_LOADED + f"from socialnav.scenarios import {name}\n{call}\n"
            "from socialnav.scenarios import registry\n"
            "print(sorted(registry._REGISTRY) == sorted(registry.list_scenarios()))\n"
        )
        assert out.strip() == "True", name


def test_registering_a_builtin_name_fails_before_any_lookup():
    out = run_fresh(
        NOTHING_LOADED + "from dataclasses import dataclass\n"
        "from socialnav.scenarios import Scenario, register_scenario\n"
        "@dataclass(frozen=True, kw_only=True)\n"
        "class Mine(Scenario):\n"
        "    def sample_humans(self, rng, indices):\n"
        "        raise NotImplementedError\n"
        "try:\n"
        "    register_scenario('circle_crossing')(Mine)\n"
        "except ValueError as err:\n"
        "    print(err)\n"
    )
    assert out.strip() == (
        "scenario name 'circle_crossing' is already registered to "
        "socialnav.scenarios.circle.CircleCrossing"
    )


def test_scenario_classes_resolve_lazily_and_are_listed_by_dir():
    out = run_fresh(
        NOTHING_LOADED + "assert 'CircleCrossing' in dir(socialnav.scenarios)\n"
        "assert 'socialnav.scenarios.circle' not in sys.modules  # dir() loads nothing\n"
        "cls = socialnav.scenarios.CircleCrossing\n"
        "from socialnav.scenarios.circle import CircleCrossing\n"
        "assert cls is CircleCrossing and cls.name == 'circle_crossing'\n"
        "from socialnav.scenarios import SquareCrossing, get_scenario\n"
        "assert get_scenario('square_crossing') is SquareCrossing\n"
        "missing = set(socialnav.scenarios.__all__) - set(dir(socialnav.scenarios))\n"
        "assert not missing, missing\n"
        "print('ok')\n"
    )
    assert out.strip() == "ok"


def test_importing_one_builtin_module_registers_them_all():
    # what a worker process does when it unpickles a scenario: import its class's module only
    out = run_fresh(
        NOTHING_LOADED + "import pickle\n"
        "from socialnav.scenarios.single import Passing\n"
        "data = pickle.dumps(Passing(n_offsets=3))\n"
        "print(data.hex())\n"
    )
    blob = out.strip()
    out = run_fresh(
        "import pickle, sys\n"
        f"scenario = pickle.loads(bytes.fromhex({blob!r}))\n"
        "from socialnav.scenarios import registry\n"
        "assert type(scenario).name == 'passing' and scenario.n_offsets == 3\n"
        "print(' '.join(sorted(registry._REGISTRY)))\n"
    )
    assert documented_builtins() <= set(out.split())


def test_a_builtin_module_that_fails_to_import_fails_every_lookup(monkeypatch: pytest.MonkeyPatch):
    # not "unknown scenario" on the second lookup: the loaded flag is reset after the failure
    from socialnav.scenarios import registry

    monkeypatch.setattr(registry, "_builtins_state", "unloaded")
    monkeypatch.setattr(registry, "BUILTIN_MODULES", (*registry.BUILTIN_MODULES, "socialnav.nowhere"))
    for _ in range(2):
        with pytest.raises(ModuleNotFoundError, match="socialnav.nowhere"):
            registry.get_scenario("circle_crossing")
    assert registry._builtins_state == "unloaded"


def test_threads_looking_up_first_all_see_every_builtin(tmp_path: Path):
    # one thread imports the built-ins; the others wait for it instead of seeing a half-filled registry
    # (a slow module loaded first widens the window in which they would)
    (tmp_path / "slow_builtin.py").write_text("import time\ntime.sleep(0.3)\n", encoding="utf-8")
    out = run_fresh(
        NOTHING_LOADED + "import threading\n"
        f"sys.path.insert(0, {str(tmp_path)!r})\n"
        "from socialnav.scenarios import list_scenarios, registry\n"
        "registry.BUILTIN_MODULES = ('slow_builtin', *registry.BUILTIN_MODULES)\n"
        "barrier = threading.Barrier(8)\n"
        "seen = []\n"
        "def look():\n"
        "    barrier.wait()\n"
        "    seen.append(len(list_scenarios()))\n"
        "threads = [threading.Thread(target=look) for _ in range(8)]\n"
        "[t.start() for t in threads]\n"
        "[t.join() for t in threads]\n"
        "print(sorted(set(seen)))\n"
    )
    counts = ast.literal_eval(out.strip())
    assert len(counts) == 1 and counts[0] >= len(documented_builtins())


def test_another_class_of_the_same_name_cannot_take_a_builtin_name():
    # a class that only shares the built-in's qualified name (another module) is refused
    from socialnav.scenarios import CircleCrossing, register_scenario

    clash = type(CircleCrossing.__name__, (CircleCrossing,), {"__module__": "someone.elses"})
    clash = dataclasses.dataclass(frozen=True)(clash)
    with pytest.raises(ValueError, match="already registered to socialnav.scenarios.circle.CircleCrossing"):
        register_scenario("circle_crossing")(clash)
