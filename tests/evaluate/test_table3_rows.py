"""Table III keeps a policy that was run on the single-human scenarios but never succeeded there (its
cells are "–", explained under the table), and leaves out a policy that was not run on them."""

import math

from socialnav.evaluate.report import TABLE3_COUNTS_NOTE, TABLE3_DASH_NOTE, table3, table3_rows

SIDE = ("passing", "overtaking", "crossing")


def side_rows(policy, left, right):
    return [
        {"policy": policy, "scenario": s, "visibility": "invisible",
         "m6_left_pct": left, "m6_right_pct": right}
        for s in SIDE
    ]


def test_a_policy_with_no_successful_single_human_case_keeps_a_row_of_dashes():
    summary = side_rows("good", 25.0, 75.0) + side_rows("stuck", math.nan, math.nan)
    rows = table3_rows(summary)
    assert rows == [["good"] + ["25", "75", "–", "–"] * 3, ["stuck"] + ["–"] * 12]
    md = table3(summary, "md")
    assert "| stuck |" + " – |" * 12 in md
    assert TABLE3_DASH_NOTE in md
    tex = table3(summary, "tex")
    assert tex.rstrip().endswith("% " + TABLE3_DASH_NOTE)


def test_a_policy_not_run_on_single_human_scenarios_has_no_row_and_no_note_without_dashes():
    multi = {"policy": "multi_only", "scenario": "circle_crossing", "visibility": "invisible"}
    summary = side_rows("good", 40.0, 60.0) + [multi]
    assert [r[0] for r in table3_rows(summary)] == ["good"]
    assert TABLE3_DASH_NOTE not in table3(summary, "md")
    assert table3([multi], "md") == ""


def test_each_case_gives_the_labelled_cases_and_the_failures_split_by_outcome():
    # social force overtaking in 20 episodes: 2 successes (1 left, 1 right), 18 collisions
    row = {"policy": "social_force", "scenario": "overtaking", "visibility": "invisible", "episodes": 20,
           "collision_rate": 0.9, "timeout_rate": 0.0, "m6_left_pct": 50.0, "m6_right_pct": 50.0,
           "m6_n_labelled": 2.0, "m6_n_failed": 18.0}
    passing = {**row, "scenario": "passing", "collision_rate": 0.0, "m6_n_labelled": 19.0,
               "m6_n_failed": 0.0, "m6_left_pct": 100 * 7 / 19, "m6_right_pct": 100 * 12 / 19}
    crossing = {**row, "scenario": "crossing", "collision_rate": 0.75, "timeout_rate": 0.25,
                "m6_left_pct": None, "m6_right_pct": None, "m6_n_labelled": 0.0, "m6_n_failed": 20.0}
    (cells,) = table3_rows([passing, row, crossing])
    assert cells == ["social_force", "37", "63", "19", "0", "50", "50", "2", "18 (18 c, 0 t)",
                     "–", "–", "0", "20 (15 c, 5 t)"]
    md = table3([passing, row, crossing], "md")
    assert "| Overtaking n | Overtaking failed |" in md
    assert TABLE3_COUNTS_NOTE in md and TABLE3_DASH_NOTE in md
    assert "% " + TABLE3_COUNTS_NOTE in table3([row], "tex")
    assert TABLE3_DASH_NOTE not in table3([passing, row, {**passing, "scenario": "crossing"}], "md")


def test_one_human_encounters_among_the_multi_human_scenarios_get_their_side_preference(tmp_path):
    # francis2023's frontal_approach and narrow_hallway meet one human head-on (the spec: M_VI applies to
    # Francis (a) and (j)): their Table II rows stay, and Table III gets a part of their own
    import dataclasses

    from socialnav.evaluate.runner import run_protocol
    from socialnav.metrics import side_case_of_row
    from socialnav.policies.building import build_policy
    from socialnav.presets import load_preset

    preset = load_preset("francis2023")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, episodes=6))
    result = run_protocol(build_policy("orca", preset), preset, tmp_path,
                          scenarios=["frontal_approach", "intersection"], visibility="invisible",
                          progress=False, trajectories=False)
    rows = {r["scenario"]: r for r in result.summary}
    frontal = rows["frontal_approach"]
    assert frontal["single_human"] is False and rows["intersection"]["single_human"] is False
    assert "m6_left_pct" not in rows["intersection"]  # four crossing people: no passing side
    # the counts are the episode rows' cases, by hand
    cases = [side_case_of_row(r) if r["outcome"] == "success" else "failed"
             for r in result.rows if r["scenario"] == "frontal_approach"]
    assert frontal["m6_n_left"] == cases.count("left") and frontal["m6_n_right"] == cases.count("right")
    assert frontal["m6_n_failed"] == cases.count("failed") and len(cases) == 6
    table2_text = (tmp_path / "table2.md").read_text()
    assert "### Table II, frontal_approach" in table2_text
    text = (tmp_path / "table3.md").read_text()
    assert "Table III, one-human encounters among the multi-human scenarios" in text
    assert "| Policy | frontal_approach L % | frontal_approach R % | frontal_approach n |" in text
    assert f"| orca | {frontal['m6_left_pct']:.0f} | {frontal['m6_right_pct']:.0f} |" in text
