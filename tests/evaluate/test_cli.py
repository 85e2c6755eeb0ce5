"""End-to-end runs of the `socialnav` command line on small workloads."""

import json

import numpy as np
import pytest

from socialnav.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_evaluate_full_wang2022_protocol_fills_every_table_column(tmp_path, capsys):
    code, out, err = run(
        capsys,
        "evaluate",
        "--policy",
        "orca",
        "--preset",
        "wang2022",
        "--out",
        str(tmp_path),
        "--no-progress",
    )
    assert code == 0, err
    table2 = out.split("### Table II: pooled")[1].split("###")[0]
    policy_row = [line for line in table2.splitlines() if line.startswith("| orca")][0]
    cells = [c.strip() for c in policy_row.strip("|").split("|")]
    assert len(cells) == 12 and "–" not in cells, cells
    table3 = out.split("### Table III")[1]
    row3 = [line for line in table3.splitlines() if line.startswith("| orca")][0]
    assert "–" not in row3, row3
    # the M_V caveat is stated once, in the table's notes, not as a warning on every run
    assert "Note: robot v_pref 1.5 m/s <= v_th 1.5 m/s" in out and "M_V" not in err
    assert (tmp_path / "table2.md").read_text().count("Note: robot v_pref") == 1
    assert "Note: mean ± standard deviation over episodes, not a confidence interval" in out
    summary = json.loads((tmp_path / "summary.json").read_text())
    pooled = [r for r in summary["rows"] if r["scenario"] == "pooled" and r["visibility"] == "invisible"][0]
    assert pooled["episodes"] == 2000


def test_evaluate_json_prints_one_object_with_rows(tmp_path, capsys):
    code, out, _ = run(
        capsys,
        "evaluate",
        "--preset",
        "crowdnav",
        "--episodes",
        "30",
        "--out",
        str(tmp_path),
        "--json",
        "--no-progress",
    )
    assert code == 0
    data = json.loads(out)
    row = data["rows"][0]
    for key in (
        "policy",
        "scenario",
        "visibility",
        "episodes",
        "success_rate",
        "collision_rate",
        "timeout_rate",
        "nav_time_s",
        "m1_personal_space.duration_s@eps=0.2,distance=clearance.mean",
        "m4_jerk.mean_sq.std",
    ):
        assert key in row, key
    assert row["episodes"] == 30 and row["policy"] == "orca"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["evaluate", "--scenario", "plaza"],
         "unknown scenario 'plaza'; valid scenarios: blind_corner, circle_crossing"),
        (["evaluate", "--policy", "teleport"], "unknown policy 'teleport'; valid: cadrl"),
        (["evaluate", "--preset", "nowhere"],
         "unknown preset 'nowhere'; shipped: crowdnav, francis2023, wang2022"),
        # om_sarl ships for wang2022 only: under crowdnav a checkpoint path is required
        (["evaluate", "--policy", "om_sarl", "--preset", "crowdnav"], "pass --checkpoint"),
        (["evaluate", "--episodes", "0"], "episodes must be >= 1"),
    ],
)
def test_evaluate_bad_input_is_one_clear_line(tmp_path, capsys, argv, message):
    code, _, err = run(capsys, *argv, "--out", str(tmp_path / "x"), "--no-progress")
    assert code == 2
    assert message in err and "Traceback" not in err


def test_preset_file_with_unknown_key_names_file_and_field(tmp_path, capsys):
    bad = tmp_path / "mine.yaml"
    bad.write_text("name: mine\nworld:\n  dt: 0.25\n  horizon: 3\n")
    code, _, err = run(capsys, "evaluate", "--preset", str(bad), "--out", str(tmp_path / "o"))
    assert code == 2 and "mine.yaml" in err and "world.horizon" in err


def test_metrics_command_scores_a_trajectory_file(tmp_path, capsys):
    from socialnav.policies import make_policy
    from socialnav.scenarios import make_scenario
    from socialnav.sim.settings import WorldSettings
    from socialnav.sim.world import World
    from socialnav.trajectory import write_trajectories

    world = World(WorldSettings(), make_scenario("passing", n_humans=1, robot_v_pref=1.0), 4, count=4)
    policy = make_policy("orca", safety_space=0.2)
    world.reset()
    trajs = []
    while world.busy:
        trajs += world.step(policy.act(world.observe())).finished
    for suffix in ("parquet", "csv"):
        path = tmp_path / f"log.{suffix}"
        write_trajectories(path, trajs)
        code, out, err = run(capsys, "metrics", str(path), "--json")
        assert code == 0, err
        data = json.loads(out)
        assert len(data["episodes"]) == 4
        assert {e["outcome"] for e in data["episodes"]} <= {"success", "collision", "timeout"}
        first = data["episodes"][0]
        assert np.isfinite(first["path_length"]) and first["path_length"] > 7.0


def test_metrics_command_rejects_bad_file_naming_it(tmp_path, capsys):
    bad = tmp_path / "broken.csv"
    bad.write_text("episode,t,agent,role,x\n0,0.0,0,robot,0.0\n")
    code, _, err = run(capsys, "metrics", str(bad))
    assert code == 2 and "broken.csv" in err


def test_list_json(capsys):
    code, out, _ = run(capsys, "list", "--json")
    data = json.loads(out)
    assert code == 0
    assert {"circle_crossing", "passing", "square_crossing"} <= set(data["scenarios"])
    assert {"orca", "sarl"} <= {p["name"] for p in data["policies"]}
    assert {"m1_personal_space", "m6_side_preference"} <= {m["name"] for m in data["metrics"]}
    assert data["human_models"] == ["orca", "social_force", "linear"]


def test_list_prints_each_scenario_parameter_with_its_unit_and_constraint(capsys):
    # the same parameter table as the scenario's declaration and docs/reference/settings.md
    code, out, _ = run(capsys, "list", "--json")
    assert code == 0
    params = {p["name"]: p for p in json.loads(out)["scenarios"]["parallel_traffic"]}
    assert params["robot_v_pref"] == {"name": "robot_v_pref", "default": 1.0, "type": "float", "unit": "m/s",
                                      "constraint": "> 0", "doc": "robot preferred (maximum) speed"}
    assert (params["traffic_area"]["unit"], params["traffic_area"]["constraint"]) == (
        "", "one of 'half_square', 'band'")
    code, out, _ = run(capsys, "list")
    line = next(x for x in out.splitlines() if x.startswith("  parallel_traffic: "))
    assert line.startswith("  parallel_traffic: n_humans=5 (>= 0), robot_radius=0.3 m (> 0), ")
    assert ", randomize_attributes=False, " in line  # no unit, no constraint: the default alone
    assert ", random_v_pref_range=(0.5, 1.5) m/s, random_radius_range=(0.3, 0.5) m, " in line
    assert line.endswith(", traffic_area=half_square (one of 'half_square', 'band'), band_width=2.0 m (> 0)")
    # Learned policies' bracketed settings are registry defaults; the listing says a checkpoint's win.
    assert "information and planning settings come from its checkpoint unless given" in out
