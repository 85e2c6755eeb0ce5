"""The protocol runner: results, resumption after an interruption, refusal of a foreign directory."""

import dataclasses
import json
import os

import numpy as np
import pytest

import socialnav.evaluate.execution as execution_module
from socialnav.evaluate.runner import ResumeMismatchError, run_protocol
from socialnav.policies import make_policy
from socialnav.presets import load_preset


def small_preset(**evaluation):
    preset = load_preset("wang2022")
    settings = {"episodes": 12, "chunk_size": 5, **evaluation}
    return dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, **settings))


@pytest.fixture
def orca():
    return make_policy("orca", safety_space=0.2)


def test_run_writes_every_result_file_and_consistent_rates(tmp_path, orca):
    result = run_protocol(
        orca, small_preset(), tmp_path, scenarios=["circle_crossing", "random", "passing"], progress=False
    )
    for name in (
        "manifest.json",
        "summary.json",
        "summary.csv",
        "table2.md",
        "table2.tex",
        "table3.md",
        "table3.tex",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    # 12 episodes in chunks of 5 = 3 files per pass (two passes per multi-human scenario); passing 20 / 5
    assert len(list((tmp_path / "episodes").rglob("*.parquet"))) == 2 * 3 + 2 * 3 + 4
    by_key = {(r["scenario"], r["visibility"]): r for r in result.summary}
    for key in [
        ("circle_crossing", "invisible"),
        ("circle_crossing", "visible"),
        ("random", "invisible"),
        ("pooled", "invisible"),
        ("pooled", "visible"),
        ("passing", "invisible"),
    ]:
        row = by_key[key]
        assert row["success_rate"] + row["collision_rate"] + row["timeout_rate"] == pytest.approx(1.0)
    assert by_key[("pooled", "invisible")]["episodes"] == 24
    assert by_key[("passing", "invisible")]["episodes"] == 20
    passing = by_key[("passing", "invisible")]
    assert passing["m6_n_labelled"] + passing["m6_n_unlabelled"] + passing["m6_n_failed"] == 20
    # M_III comes from the visible pass (continuation) and counts steps = 4 x seconds at dt 0.25.
    vis = by_key[("circle_crossing", "visible")]
    assert vis["m3_aggregated_time.steps@cap_s=100.mean"] == pytest.approx(
        4 * vis["m3_aggregated_time.time_s@cap_s=100.mean"]
    )
    # Bootstrap intervals bracket the mean.
    inv = by_key[("pooled", "invisible")]
    assert inv["success_rate_ci_low"] <= inv["success_rate"] <= inv["success_rate_ci_high"]


def test_the_pooled_row_is_over_every_multi_human_scenario_the_run_evaluated(tmp_path, orca):
    # francis2023's multi_human list has no circle_crossing: asked for beside narrow_doorway, both are
    # pooled (the pooled row was missing and Table II showed circle_crossing's row under "pooled")
    preset = load_preset("francis2023")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, episodes=3))
    result = run_protocol(orca, preset, tmp_path, scenarios=["circle_crossing", "narrow_doorway"],
                          visibility="invisible", progress=False, trajectories=False)
    by_scenario = {r["scenario"]: r for r in result.summary}
    pooled = by_scenario["pooled"]
    assert pooled["pooled_over"] == "circle_crossing,narrow_doorway" and pooled["episodes"] == 6
    rates = [by_scenario[s]["success_rate"] for s in ("circle_crossing", "narrow_doorway")]
    expected = sum(rates) / 2
    assert pooled["success_rate"] == pytest.approx(expected)
    table = (tmp_path / "table2.md").read_text().split("### Table II, circle_crossing")[0]
    assert f"| orca | {100 * expected:.2f} |" in table


def test_interrupted_run_resumes_without_recomputing(tmp_path, orca, monkeypatch):
    preset = small_preset()
    real = execution_module.simulate_chunk
    calls = {"n": 0}

    def flaky(*args, **kwargs):
        calls["n"] += 1
        if calls["n"] == 3:
            raise KeyboardInterrupt  # killed in the middle of the third chunk
        return real(*args, **kwargs)

    monkeypatch.setattr(execution_module, "simulate_chunk", flaky)
    with pytest.raises(KeyboardInterrupt):
        run_protocol(
            orca, preset, tmp_path, scenarios=["circle_crossing"], visibility="invisible", progress=False
        )
    files = sorted((tmp_path / "episodes").rglob("*.parquet"))
    assert len(files) == 2 and not list(tmp_path.rglob("*.tmp"))  # finished chunks kept, no partial file
    stamps = {f: os.stat(f).st_mtime_ns for f in files}
    monkeypatch.setattr(execution_module, "simulate_chunk", real)
    result = run_protocol(
        orca, preset, tmp_path, scenarios=["circle_crossing"], visibility="invisible", progress=False
    )
    assert result.computed_episodes == 2  # only the missing chunk (episodes 10-11)
    assert all(os.stat(f).st_mtime_ns == stamps[f] for f in files)
    assert sorted(r["index"] for r in result.rows) == list(range(12))
    fresh = run_protocol(
        orca,
        preset,
        tmp_path / "fresh",
        scenarios=["circle_crossing"],
        visibility="invisible",
        progress=False,
    )
    assert [r["outcome"] for r in fresh.rows] == [r["outcome"] for r in result.rows]


def test_directory_of_another_run_is_refused(tmp_path, orca):
    run_protocol(orca, small_preset(), tmp_path, scenarios=["random"], visibility="invisible", progress=False)
    with pytest.raises(ResumeMismatchError, match=r"cells\[random/invisible\]\.episodes: 12 -> 7"):
        run_protocol(
            orca,
            small_preset(episodes=7),
            tmp_path,
            scenarios=["random"],
            visibility="invisible",
            progress=False,
        )
    with pytest.raises(ResumeMismatchError, match=r"policy\.safety_space: 0\.2 -> 0\.1"):
        run_protocol(
            make_policy("orca", safety_space=0.1),
            small_preset(),
            tmp_path,
            scenarios=["random"],
            visibility="invisible",
            progress=False,
        )


def test_unknown_scenario_lists_valid_names(tmp_path, orca):
    with pytest.raises(KeyError, match="valid scenarios: blind_corner, circle_crossing, "
                       "circle_crossing_obstacles, crossing"):
        run_protocol(orca, small_preset(), tmp_path, scenarios=["plaza"], progress=False)


def test_summary_json_rows_hold_every_metric_mean_and_std(tmp_path, orca):
    run_protocol(
        orca, small_preset(), tmp_path, scenarios=["circle_crossing"], visibility="invisible", progress=False
    )
    data = json.loads((tmp_path / "summary.json").read_text())
    from socialnav.metrics import score_keys

    for row in data["rows"]:
        for key in score_keys():
            if key in ("success", "collision", "timeout", "wall_collision"):  # rates: <name>_rate
                continue
            assert f"{key}.mean" in row and f"{key}.std" in row, key
    assert np.isfinite(data["rows"][0]["nav_time_s"])


def test_a_policy_built_without_the_presets_policy_settings_is_said(tmp_path):
    # crowdnav's policies section sets ORCA's safety space to 0: `socialnav evaluate` applies it
    # (build_policy); make_policy has the registry's 0.2, so the run would not be the CLI's
    import warnings

    from socialnav.policies.building import build_policy

    preset = load_preset("crowdnav")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, episodes=1))
    with pytest.warns(UserWarning, match=r"policy 'orca' runs with safety_space = 0.2 \(the preset: 0.0\): "
                      r"preset 'crowdnav' sets these for it"):
        run_protocol(make_policy("orca"), preset, tmp_path / "a", progress=False, trajectories=False)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run_protocol(build_policy("orca", preset), preset, tmp_path / "b", progress=False, trajectories=False)
        # overridden on purpose through build_policy: nothing to say either
        run_protocol(build_policy("orca", preset, safety_space=0.2), preset, tmp_path / "c", progress=False,
                     trajectories=False)
