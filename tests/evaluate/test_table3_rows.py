"""Table III keeps a policy that was run on the single-human scenarios but never succeeded there (its
cells are "–", explained under the table), and leaves out a policy that was not run on them."""

import math

from socialnav.evaluate.report import TABLE3_DASH_NOTE, table3, table3_rows

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
    assert rows == [["good"] + ["25", "75"] * 3, ["stuck"] + ["–"] * 6]
    md = table3(summary, "md")
    assert "| stuck | – | – | – | – | – | – |" in md
    assert TABLE3_DASH_NOTE in md
    tex = table3(summary, "tex")
    assert tex.rstrip().endswith("% " + TABLE3_DASH_NOTE)


def test_a_policy_not_run_on_single_human_scenarios_has_no_row_and_no_note_without_dashes():
    multi = {"policy": "multi_only", "scenario": "circle_crossing", "visibility": "invisible"}
    summary = side_rows("good", 40.0, 60.0) + [multi]
    assert [r[0] for r in table3_rows(summary)] == ["good"]
    assert TABLE3_DASH_NOTE not in table3(summary, "md")
    assert table3([multi], "md") == ""
