"""Small things of the result tables: LaTeX symbols, one multi-human scenario, bad reproduce options."""

from __future__ import annotations

import pytest

from socialnav.cli import main
from socialnav.evaluate.report import _render, table2


def test_the_comparison_columns_are_valid_latex():
    tex = _render("t", ["Δ ours − paper", "M_V≥ (s)"], [["−0.5 ± 0.1"]], "tex")
    assert "$\\Delta$ ours $-$ paper" in tex and "M\\_V$\\geq$ (s)" in tex and "$-$0.5 $\\pm$ 0.1" in tex
    assert not any(ch in tex for ch in "Δ−±≥")


def test_one_multi_human_scenario_is_one_table_by_its_name():
    row = {"policy": "orca", "scenario": "circle_crossing", "visibility": "invisible", "single_human": False,
           "episodes": 3, "success_rate": 1.0, "collision_rate": 0.0, "timeout_rate": 0.0}
    text = table2([row])
    assert "pooled" not in text and text.count("### Table II") == 1
    assert "### Table II, circle_crossing (invisible robot; M_III needs the visible pass" in text


def test_a_visible_only_policy_is_marked_in_a_table_of_the_invisible_robot():
    def row(policy, visibility, success):
        return {"policy": policy, "scenario": "circle_crossing", "visibility": visibility,
                "single_human": False, "episodes": 4, "success_rate": success, "collision_rate": 0.0,
                "timeout_rate": 1 - success}

    rows = [row("orca", "invisible", 0.5), row("orca", "visible", 0.75), row("linear", "visible", 1.0)]
    text = table2(rows)
    assert "| orca | 50.00 |" in text  # the invisible pass, as the title says
    assert "| linear (visible robot only) | 100.00 |" in text
    assert "Note: a row marked (visible robot only) is of a policy run with a visible robot only" in text
    alone = table2([row("linear", "visible", 1.0)])  # the title already says visible only: no mark
    assert "(visible robot only; M_I, M_II, M_IV, M_V need the invisible pass)" in alone.splitlines()[0]
    assert "| linear | 100.00 |" in alone
    assert "Note: a row marked" not in alone


@pytest.mark.parametrize("workers", ["-2"])
def test_reproduce_refuses_a_negative_worker_count(tmp_path, capsys, workers):
    assert main(["reproduce", "--quick", "--workers", workers, "--out", str(tmp_path / "r")]) == 2
    assert "--workers must be >= 0 (0: simulate and score in this process), got -2" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


def test_a_directory_of_another_kind_of_run_is_refused(tmp_path, capsys):
    # their top-level summary and tables share names: one kind's run overwrote the other's conclusion
    one = ["evaluate", "--policy", "orca", "--scenario", "circle_crossing", "--episodes", "1", "--quiet"]
    assert main([*one, "--out", str(tmp_path / "single")]) == 0
    every = ["evaluate", "--policy", "all", "--scenario", "circle_crossing", "--episodes", "1", "--quiet"]
    assert main([*every, "--out", str(tmp_path / "single")]) == 2
    assert ("single holds the results of an evaluation of one policy (manifest.json); this is `evaluate "
            "--policy all`: use another --out") in capsys.readouterr().err
    (tmp_path / "several" / "policies").mkdir(parents=True)  # what `evaluate --policy all` leaves
    assert main([*one, "--out", str(tmp_path / "several")]) == 2
    assert "several holds the results of `evaluate --policy all` (policies)" in capsys.readouterr().err
    assert main(["reproduce", "--quick", "--out", str(tmp_path / "single")]) == 2
    assert "this is `socialnav reproduce`: use another --out" in capsys.readouterr().err


def test_a_run_larger_than_the_test_split_is_refused_before_any_file(tmp_path, capsys):
    argv = ["evaluate", "--policy", "linear", "--scenario", "random", "--visibility", "invisible",
            "--episodes", "1001", "--out", str(tmp_path / "out"), "--no-progress"]
    assert main(argv) == 2
    said = "random: 1001 episodes (--episodes / evaluation.episodes), more than the 1000 of the 'test' split"
    assert said in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
