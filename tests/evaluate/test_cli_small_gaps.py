"""Smaller CLI gaps: --version, `list` shows Gym ids and shipped checkpoints, an episode count above a
single-human sweep's size is warned about, and tables without rows are not printed."""

import json

import pytest

from socialnav import __version__
from socialnav.cli import main


def run(capsys, *argv):
    code = main(list(argv))
    out = capsys.readouterr()
    return code, out.out, out.err


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"socialnav {__version__}"


def test_the_manifest_records_the_version_and_a_newer_release_resumes(tmp_path, capsys):
    out = tmp_path / "run"
    code, _, err = run(capsys, "evaluate", "--scenario", "passing", "--episodes", "4", "--out", str(out),
                       "--quiet")
    assert code == 0, err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["socialnav_version"] == __version__
    # a run started by another release resumes (the version is recorded, not part of the run's identity)
    (out / "manifest.json").write_text(json.dumps({**manifest, "socialnav_version": "0.0.1"}))
    code, printed, err = run(capsys, "evaluate", "--scenario", "passing", "--episodes", "4", "--out",
                             str(out), "--json", "--no-progress")
    assert code == 0, err
    assert json.loads(printed)["rows"][0]["episodes"] == 4
    assert json.loads((out / "manifest.json").read_text())["socialnav_version"] == "0.0.1"


def test_preset_show_prints_a_file_that_loads_as_the_shipped_preset(tmp_path, capsys):
    from socialnav.presets import load_preset, shipped_presets

    code, out, _ = run(capsys, "preset", "list")
    assert code == 0
    assert [line.split(":")[0] for line in out.splitlines()] == shipped_presets()
    for name in shipped_presets():
        code, out, err = run(capsys, "preset", "show", name)
        assert code == 0, err
        assert out.startswith(f"# The shipped preset {name!r}")
        path = tmp_path / f"{name}.yaml"
        path.write_text(out)
        assert load_preset(path) == load_preset(name)
    # edited and run, as the header says
    path.write_text(out.replace(f"name: {name}", "name: mine"))
    assert load_preset(path).name == "mine"
    code, _, err = run(capsys, "preset", "show", "nope")
    assert code == 2 and "unknown preset 'nope'; shipped: crowdnav" in err


def test_table3_on_stdout_gives_labelled_cases_and_failures(tmp_path, capsys):
    code, out, err = run(capsys, "evaluate", "--policy", "social_force", "--scenario", "overtaking",
                         "--episodes", "20", "--out", str(tmp_path), "--no-progress")
    assert code == 0, err
    summary = json.loads((tmp_path / "summary.json").read_text())
    (row,) = [r for r in summary["rows"] if r["visibility"] == "invisible"]
    header, _, cells = out.split("### Table III")[1].strip().splitlines()[2:5]
    cells = dict(zip(header.strip("|").split("|"), cells.strip("|").split("|"), strict=True))
    cells = {k.strip(): v.strip() for k, v in cells.items()}
    failed = row["episodes"] - round(row["success_rate"] * row["episodes"])
    assert cells["Overtaking n"] == str(int(row["m6_n_labelled"]))
    assert cells["Overtaking failed"].split(" ")[0] == str(failed)
    assert cells["Passing n"] == "–"  # not run


def test_list_shows_gym_ids_and_shipped_checkpoints(capsys):
    code, out, _ = run(capsys, "list", "--json")
    assert code == 0
    data = json.loads(out)
    assert data["gym_ids"]["socialnav/Passing-v0"] == "passing"
    assert data["gym_ids"]["socialnav/CircleCrossing-v0"] == "circle_crossing"
    assert {"sarl_crowdnav", "sarl_wang2022"} <= set(data["checkpoints"])
    code, out, _ = run(capsys, "list")
    assert "socialnav/Crossing-v0: crossing" in out
    assert "sarl_wang2022" in out


def test_too_many_episodes_for_a_single_human_sweep_is_warned(tmp_path, capsys):
    code, out, err = run(capsys, "evaluate", "--scenario", "passing", "--episodes", "5000", "--out",
                         str(tmp_path), "--no-progress", "--json")
    assert code == 0, err
    assert "warning: passing has 20 episodes" in err and "not the 5000 asked for" in err
    assert json.loads(out)["rows"][0]["episodes"] == 20


def test_only_tables_with_rows_are_printed(tmp_path, capsys):
    code, out, err = run(capsys, "evaluate", "--scenario", "passing", "--out", str(tmp_path / "a"),
                         "--no-progress")
    assert code == 0, err
    assert "Table III" in out and "Table II" not in out.replace("Table III", "")
    assert "no multi-human scenario was evaluated" in (tmp_path / "a" / "table2.md").read_text()
    code, out, err = run(capsys, "evaluate", "--preset", "crowdnav", "--episodes", "4", "--out",
                         str(tmp_path / "b"), "--no-progress")
    assert code == 0, err
    assert "Table II" in out and "Table III" not in out
    assert "| orca" in out
    assert (tmp_path / "b" / "table3.tex").read_text().startswith("% no single-human scenario")


def test_single_human_scenarios_say_what_a_small_or_visible_run_leaves_out(tmp_path):
    from socialnav.evaluate.plan import plan_cells
    from socialnav.presets import load_preset
    from socialnav.settings import ConfigError

    preset = load_preset("wang2022")
    with pytest.warns(UserWarning, match=r"passing: 10 of its 20 lateral offsets \(episodes 0-9: -0.60 to "
                      r"-0.03 m\)"):
        (cell,) = plan_cells(preset, ["passing"], episodes=10)
    assert cell.episodes == 10
    with pytest.warns(UserWarning, match="passing is a single-human scenario, evaluated with an invisible "
                      "robot only"):
        cells = plan_cells(preset, ["circle_crossing", "passing"], episodes=4, visibility="visible")
    assert [(c.scenario, c.visibility) for c in cells] == [("circle_crossing", "visible")]
    with pytest.raises(ConfigError, match="nothing to evaluate"), pytest.warns(UserWarning):
        plan_cells(preset, ["passing"], visibility="visible")


def test_the_same_scenarios_in_another_order_name_the_order(tmp_path, capsys):
    argv = ["evaluate", "--policy", "linear", "--episodes", "2", "--out", str(tmp_path), "--quiet"]
    assert main([*argv, "--scenario", "crossing", "passing"]) == 0
    capsys.readouterr()
    assert main([*argv, "--scenario", "passing", "crossing"]) == 2
    assert ("differs in: the order of the cells: crossing/invisible, passing/invisible before, "
            "passing/invisible, crossing/invisible now; give --scenario in the previous order to resume"
            ) in capsys.readouterr().err


def test_labels_are_text_in_every_table_and_never_a_path(tmp_path, capsys, monkeypatch):
    from socialnav.evaluate.report import table2

    row = {"policy": "a&b_#{x}~$|", "scenario": "circle_crossing", "visibility": "invisible", "episodes": 1,
           "success_rate": 1.0}
    tex = table2([row], "tex")
    assert "a\\&b\\_\\#\\{x\\}\\textasciitilde{}\\$|" in tex
    assert "| a&b_#{x}~$\\| |" in table2([row], "md")
    monkeypatch.chdir(tmp_path)
    argv = ["evaluate", "--policy", "linear", "--scenario", "passing", "--episodes", "2", "--quiet"]
    assert main([*argv, "--label", "../../x"]) == 2
    assert "outside runs/evaluate: pass --out" in capsys.readouterr().err
    assert not (tmp_path.parent / "x").exists() and not (tmp_path / "runs").exists()


def test_table2_titles_say_which_pass_a_run_lacks():
    from socialnav.evaluate.report import table2

    row = {"scenario": "circle_crossing", "episodes": 1, "success_rate": 1.0}
    assert "M_III needs the visible pass" in table2([{**row, "policy": "p", "visibility": "invisible"}])
    assert "visible robot only" in table2([{**row, "policy": "p", "visibility": "visible"}])
    both = table2([{**row, "policy": "p", "visibility": v} for v in ("invisible", "visible")])
    assert "(invisible robot; M_III visible)" in both


def test_small_command_line_conveniences(tmp_path, capsys):
    import subprocess
    import sys

    from tests._env import subprocess_env

    done = subprocess.run([sys.executable, "-m", "socialnav", "--version"], capture_output=True, text=True,
                          env=subprocess_env(), check=False)
    assert done.returncode == 0 and done.stdout.startswith("socialnav ")
    with pytest.raises(SystemExit):
        main(["preset"])
    assert "required: {list,show}" in capsys.readouterr().err
    argv = ["evaluate", "--policy", "linear", "--information", "oracle", "--scenario", "passing",
            "--episodes", "2", "--out", str(tmp_path)]
    assert main(argv) == 2
    assert ("--information applies to the value-based learned policies (CADRL, LSTM-RL, SARL, OM-SARL, RGL, "
            "MP-RGL); 'linear' has no information setting") in capsys.readouterr().err
    argv[2] = "crowdnav_pp"  # learned, but by policy gradient: no lookahead settings
    assert main(argv) == 2
    assert "'crowdnav_pp' has no information setting" in capsys.readouterr().err
    argv[2:5] = ["sarl", "--policy-arg", "information=oracle", "--information", "constant_velocity"]
    assert main(argv) == 2
    assert ("--information constant_velocity and --policy-arg information=oracle disagree; give one of them"
            in capsys.readouterr().err)
    # mp_rgl's checkpoint plans two steps with its predictor: the oracle knows one, which the message says
    # (it blamed the checkpoint: "config.value_policy is invalid")
    argv[2:7] = ["mp_rgl", "--information", "oracle", "--scenario", "passing"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    said = "'mp_rgl': information 'oracle' knows the humans' next step only, and the planning depth is 2"
    assert said in err and "invalid" not in err
