"""The HTML report: content, self-containment, and a real browser playing the episode viewer."""

import dataclasses
import json
import re
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("matplotlib")
from PIL import Image  # noqa: E402

from socialnav.cli import main  # noqa: E402
from socialnav.evaluate.runner import run_protocol  # noqa: E402
from socialnav.policies import make_policy  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402
from socialnav.viz.report import md_tables_to_html, write_report  # noqa: E402
from tests.viz.browser import Browser, find_chromium  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _run(out: Path, policy, label: str) -> Path:
    preset = load_preset("wang2022")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, chunk_size=5))
    run_protocol(
        policy,
        preset,
        out,
        label=label,
        scenarios=["circle_crossing", "random", "passing"],
        episodes=5,
        progress=False,
        workers=0,
    )
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    base = tmp_path_factory.mktemp("report")
    return [
        _run(base / "orca", make_policy("orca", safety_space=0.2), "orca"),
        _run(base / "sf", make_policy("social_force"), "social_force"),
    ]


@pytest.fixture(scope="module")
def report(runs, tmp_path_factory):
    out = tmp_path_factory.mktemp("html") / "report.html"
    info = write_report(runs, out, curves=[ROOT / "benchmarks/results/train_crowdnav_sarl_s0_curves.csv"])
    return out, info


def embedded_data(text: str) -> dict:
    m = re.search(r'<script id="episode-data" type="application/json">(.*?)</script>', text, re.S)
    return json.loads(m.group(1).replace("<\\/", "</"))


def test_every_table_is_in_the_report(runs, report):
    out, _ = report
    text = out.read_text()
    for run in runs:
        for name in ("table2.md", "table3.md"):
            for title in re.findall(r"^### (.+)$", (run / name).read_text(), re.M):
                assert f"<h3>{title}</h3>" in text, title
    # both policies are rows of the pooled Table II
    pooled = text.split("<h3>Table II: pooled")[1].split("</table>")[0]
    assert "<td>orca</td>" in pooled and "<td>social_force</td>" in pooled


def test_report_is_self_contained(report):
    text = report[0].read_text()
    assert not re.search(r"""(src|href)\s*=\s*["']?(https?:)?//""", text)  # nothing fetched from a network
    assert "<script src" not in text and "<link" not in text
    assert (
        text.count("data:image/png;base64,") == report[1]["figures"] >= 10
    )  # outcomes, M_VI, 8 metrics, curves
    assert "Training curves" in text


def test_settings_and_thresholds_are_listed(report):
    text = report[0].read_text()
    for needle in (
        "safety_space",
        "time_limit",
        "continuation_cap",
        "m1_personal_space",
        "&quot;eps&quot;: 0.2",
        "&quot;eps&quot;: 1.2",
        "m2_projected_path",
        "&quot;tau&quot;: 0.5",
        "batch_size",
    ):
        assert needle in text, needle


def test_viewer_data_picks_best_median_worst(runs, report):
    data = embedded_data(report[0].read_text())
    assert report[1]["viewer_episodes"] == len(data["episodes"])
    cells = {(c["policy"], c["scenario"], c["visibility"]) for c in data["cells"]}
    assert ("orca", "circle_crossing", "visible") in cells and (
        "social_force",
        "passing",
        "invisible",
    ) in cells
    cell = next(
        c
        for c in data["cells"]
        if (c["policy"], c["scenario"], c["visibility"]) == ("orca", "circle_crossing", "invisible")
    )
    from socialnav.evaluate.results import load_episode_rows

    rows = [
        r
        for r in load_episode_rows(runs[0])
        if r["scenario"] == "circle_crossing" and r["visibility"] == "invisible"
    ]
    times = sorted((r["navigation_time"], r["episode_id"]) for r in rows)
    picks = cell["picks"]["navigation_time"]
    assert data["episodes"][picks["best"]]["id"] == times[0][1]
    assert data["episodes"][picks["worst"]]["id"] == times[-1][1]
    assert data["episodes"][picks["median"]]["id"] == times[2][1]
    ep = data["episodes"][picks["best"]]
    n_agents = len(ep["radii"])
    assert len(ep["pos"]) == 2 * n_agents * len(ep["m1"]) and set(ep["m1"]) <= {"0", "1"}
    from socialnav.evaluate.results import load_episode

    traj = load_episode(runs[0], ep["id"])
    first = np.array(ep["pos"][: 2 * n_agents]).reshape(n_agents, 2) / data["scale"]
    np.testing.assert_allclose(first, traj.positions[0], atol=5e-4)


def test_report_cli_and_evaluate_report(tmp_path, capsys):
    out = tmp_path / "run"
    assert (
        main(
            [
                "evaluate",
                "--policy",
                "orca",
                "--scenario",
                "passing",
                "--episodes",
                "3",
                "--out",
                str(out),
                "--report",
                "--quiet",
            ]
        )
        == 0
    )
    captured = capsys.readouterr()
    # --quiet: no tables, no progress, only where the report asked for went
    assert captured.out == f"{out / 'report.html'}\n"
    assert (out / "report.html").stat().st_size > 10_000
    # Table III in the report gives the labelled cases and the failures of each case
    page = (out / "report.html").read_text()
    assert "Passing n" in page and "Passing failed" in page
    assert (out / "figures" / "outcomes.svg").read_text().lstrip().startswith("<?xml")
    assert main(["report", str(out), "--out", str(tmp_path / "r.html"), "--no-figure-files", "--quiet"]) == 0
    assert "Table III" in (tmp_path / "r.html").read_text()
    assert main(["report", str(tmp_path / "nothing")]) == 2
    assert "no such result directory" in capsys.readouterr().err


def test_md_tables_to_html_hand_made():
    md = "### T one\n\n| a | b |\n|---|---|\n| 1 | x<y |\n"
    assert md_tables_to_html(md) == (
        "<h3>T one</h3><table class='results'><thead><tr><th>a</th><th>b</th></tr></thead>"
        "<tbody><tr><td>1</td><td>x&lt;y</td></tr></tbody></table>"
    )


def test_the_notes_under_the_tables_reach_the_html():
    md = "### T\n\n| a |\n|---|\n| 1 |\n\nNote: Wall collision %: a share of <all> episodes\n"
    assert md_tables_to_html(md) == (
        "<h3>T</h3><table class='results'><thead><tr><th>a</th></tr></thead><tbody><tr><td>1</td></tr>"
        "</tbody></table>\n<p class='note'>Note: Wall collision %: a share of &lt;all&gt; episodes</p>"
    )


def canvas_pixels(path: Path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB")).astype(int)


def test_report_plays_in_headless_chromium(report, tmp_path):
    exe = find_chromium()
    if exe is None:
        pytest.skip(
            "Chromium is not installed (.ci/run installs Debian's chromium where apt-get works; "
            "or set SOCIALNAV_CHROMIUM)"
        )
    browser = Browser(exe)
    try:
        browser.open(report[0].as_uri())
        assert browser.eval("document.title").startswith("socialnav report")
        page = canvas_pixels(browser.screenshot(tmp_path / "page.png"))
        assert page.std() > 10
        before = canvas_pixels(browser.screenshot(tmp_path / "before.png", "#viewer-canvas"))
        assert 640 <= before.shape[0] <= 644 and before.std() > 5  # the canvas and its 1 px border
        assert len(np.unique(before.reshape(-1, 3), axis=0)) > 20  # discs, goals, grid: not blank
        assert browser.eval("document.getElementById('time-label').textContent") == "t = 0.00 s"
        browser.click("#btn-play")
        time.sleep(1.5)
        after = canvas_pixels(browser.screenshot(tmp_path / "after.png", "#viewer-canvas"))
        assert np.mean(np.any(before != after, axis=-1)) > 0.002  # the agents moved on the canvas
        assert browser.eval("document.getElementById('time-label').textContent") != "t = 0.00 s"
    finally:
        browser.close()


def test_runs_of_other_scenario_lists_keep_every_policy_in_the_pooled_table(runs, tmp_path):
    """One run pooled over circle_crossing and random, one of circle_crossing alone: both rows are in the
    pooled Table II (the second had been dropped), with a note that they are over different scenarios."""
    from socialnav.evaluate.report import table2

    preset = load_preset("wang2022")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, chunk_size=5))
    single = tmp_path / "linear"
    run_protocol(make_policy("linear"), preset, single, label="linear", scenarios=["circle_crossing"],
                 episodes=5, progress=False, workers=0)
    summary = [*json.loads((runs[0] / "summary.json").read_text())["rows"],
               *json.loads((single / "summary.json").read_text())["rows"]]
    pooled = table2(summary).split("Table II, ")[0]
    assert [line.split("|")[1].strip() for line in pooled.splitlines() if line.startswith("| ")][1:] == [
        "orca", "linear"]
    assert ("the pooled rows are over different scenarios, so they do not compare: orca: circle_crossing, "
            "random; linear: circle_crossing") in table2(summary)


@pytest.mark.parametrize(("damage", "message"), [
    (lambda s: '{"rows": [', r"summary.json: not valid JSON"),
    (lambda s: '{"rows": "x"}', r"summary.json: not a summary of `socialnav evaluate`"),
    (lambda s: s.replace('"success_rate": 1.0', '"success_rate": "NaN"', 1),
     r"summary.json: rows\[\d+\] \(\w+/invisible\).success_rate must be a number or null, got 'NaN'"),
])
def test_a_damaged_summary_is_named(runs, tmp_path, damage, message):
    import shutil

    run = tmp_path / "run"
    shutil.copytree(runs[0], run)
    text = (run / "summary.json").read_text()
    (run / "summary.json").write_text(damage(text))
    if "NaN" in message:
        assert '"success_rate": 1.0' in text
    with pytest.raises(ValueError, match=message):
        write_report(run, tmp_path / "r.html")


def test_a_stale_summary_and_a_damaged_manifest_are_named(runs, tmp_path):
    import shutil

    from socialnav.evaluate.results import ResultsError

    run = tmp_path / "run"
    shutil.copytree(runs[0], run)
    chunk = sorted((run / "episodes").rglob("*.parquet"))[0]
    chunk.unlink()  # as docs/protocol.md says to do with a damaged chunk, then the report is run too early
    with pytest.raises(ValueError, match=r"summary.json: stale: \w+/\w+ has 5 episodes in the summary but 0 "
                       r"in episodes/ .* run the same `socialnav evaluate` command again"):
        write_report(run, tmp_path / "r.html")
    (run / "manifest.json").write_text("[]")
    with pytest.raises(ResultsError, match="manifest.json: not a manifest of `socialnav evaluate`"):
        write_report(run, tmp_path / "r.html")
    with pytest.raises(ResultsError, match="a file, not a result directory"):
        write_report(run / "manifest.json", tmp_path / "r.html")


def test_report_arguments_that_make_no_sense_are_named(runs, tmp_path):
    with pytest.raises(ValueError, match="the same result directory is given twice"):
        write_report([runs[0], runs[0]], tmp_path / "r.html")
    with pytest.raises(ValueError, match=r"--out .* is a directory; give the report's file name"):
        write_report(runs[0], tmp_path)
    with pytest.raises(ValueError, match="--viewer-episodes must be >= 0"):
        write_report(runs[0], tmp_path / "r.html", viewer_episodes=-1)
    write_report(runs[0], tmp_path / "r.html", viewer_episodes=0)
    text = (tmp_path / "r.html").read_text()
    assert "No episode viewer (--viewer-episodes 0)." in text and "--no-trajectories" not in text
    info = write_report(runs[0], tmp_path / "r5.html", viewer_episodes=5)
    picks = embedded_data((tmp_path / "r5.html").read_text())["cells"][0]["picks"]
    assert list(next(iter(picks.values()))) == ["best", "q0.25", "median", "q0.75", "worst"]
    assert info["viewer_episodes"] > 0
