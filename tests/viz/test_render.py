"""Episode plots, animations, overlays, metric figures and the env's rgb_array rendering."""

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("matplotlib")
PIL = pytest.importorskip("PIL")
from PIL import Image  # noqa: E402

from socialnav.cli import main  # noqa: E402
from socialnav.evaluate.runner import run_protocol  # noqa: E402
from socialnav.policies import make_policy  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402
from socialnav.trajectory import Trajectory, write_trajectories  # noqa: E402
from socialnav.viz import animate  # noqa: E402
from socialnav.viz.draw import VIOLATION, frame_indices, plot_trajectory  # noqa: E402
from socialnav.viz.geometry import episode_view, parse_overlays  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("viz-run")
    preset = load_preset("wang2022")
    preset = dataclasses.replace(preset, evaluation=dataclasses.replace(preset.evaluation, chunk_size=4))
    run_protocol(
        make_policy("orca", safety_space=0.2),
        preset,
        out,
        scenarios=["circle_crossing", "passing"],
        episodes=4,
        progress=False,
        workers=0,
    )
    return out


def rgb(path) -> np.ndarray:
    return np.asarray(Image.open(path).convert("RGB"))


def assert_not_blank(img: np.ndarray) -> None:
    assert img.std() > 10, "image is (nearly) uniform"
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 20


def red_pixels(img: np.ndarray) -> int:
    r, g, b = (int(VIOLATION[i : i + 2], 16) for i in (1, 3, 5))
    return int(
        np.sum(
            (abs(img[..., 0] - r) < 30)
            & (abs(img[..., 1].astype(int) - g) < 30)
            & (abs(img[..., 2].astype(int) - b) < 30)
        )
    )


def close_pass() -> Trajectory:
    """Robot up the y axis, one human standing 0.7 m to its side: clearance 0.1 m < ε = 0.2 m at y = 0."""
    k = np.arange(9)
    robot = np.stack([np.zeros(9), -2.0 + 0.5 * k], axis=1)
    human = np.tile([0.7, 0.0], (9, 1))
    return Trajectory.from_positions(
        np.stack([robot, human], axis=1), 0.5, radii=0.3, goals=[[0, 2.5], [0.7, 0]], outcome="success"
    )


def test_plot_png_and_svg_from_a_result_directory(run_dir, tmp_path):
    png, svg = tmp_path / "ep.png", tmp_path / "ep.svg"
    assert (
        main(
            [
                "render",
                str(run_dir),
                "--episode",
                "circle_crossing/invisible/1",
                "--out",
                str(png),
                "--overlay",
                "all",
                "--quiet",
            ]
        )
        == 0
    )
    img = rgb(png)
    assert img.shape == (720, 720, 3)
    assert_not_blank(img)
    assert (
        main(["render", str(run_dir), "--episode", "passing/invisible/3", "--out", str(svg), "--quiet"]) == 0
    )
    text = svg.read_text()
    assert text.lstrip().startswith("<?xml") and "<svg" in text and "passing/invisible/3" in text


def test_default_output_goes_under_renders(run_dir):
    assert main(["render", str(run_dir), "--episode", "passing/invisible/0", "--quiet"]) == 0
    assert (run_dir / "renders" / "passing_invisible_0.png").stat().st_size > 1000


def test_gif_has_one_frame_per_sample(run_dir, tmp_path):
    from socialnav.evaluate.results import load_episode

    traj = load_episode(run_dir, "circle_crossing/visible/2")
    samples = traj.positions.shape[0] + traj.continuation.shape[0]
    out = tmp_path / "a.gif"
    assert (
        main(
            [
                "render",
                str(run_dir),
                "--episode",
                "circle_crossing/visible/2",
                "--format",
                "gif",
                "--out",
                str(out),
                "--max-frames",
                "1000",
                "--quiet",
            ]
        )
        == 0
    )
    gif = Image.open(out)
    assert gif.n_frames == samples and gif.size == (560, 560)
    gif.seek(0)
    first = np.asarray(gif.convert("RGB")).copy()
    gif.seek(gif.n_frames - 1)
    last = np.asarray(gif.convert("RGB"))
    assert_not_blank(last)
    assert np.mean(first != last) > 0.01  # the agents moved
    assert gif.info["duration"] == 250  # dt = 0.25 s at speed 1


def test_mp4_through_ffmpeg(run_dir, tmp_path):
    out = tmp_path / "a.mp4"
    if animate.ffmpeg_path() is None:
        pytest.skip("ffmpeg is not installed (.ci/run installs it where apt-get works)")
    assert (
        main(["render", str(run_dir), "--episode", "passing/invisible/1", "--out", str(out), "--quiet"]) == 0
    )
    head = out.read_bytes()[:12]
    assert head[4:8] == b"ftyp" and out.stat().st_size > 2000


def test_mp4_without_ffmpeg_is_one_clear_line(run_dir, tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(animate, "ffmpeg_path", lambda: None)
    assert (
        main(
            [
                "render",
                str(run_dir),
                "--episode",
                "passing/invisible/1",
                "--format",
                "mp4",
                "--out",
                str(tmp_path / "x.mp4"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "needs ffmpeg, which is not installed" in err and "--format gif" in err and "Traceback" not in err
    assert not (tmp_path / "x.mp4").exists()


def test_personal_space_overlay_marks_the_flagged_samples_red():
    traj = close_pass()
    view = episode_view(traj, eps=0.2)
    # hand-computed: clearance |0.7 - 0| - 0.6 = 0.1 < 0.2 only at sample 4 (y = 0)
    assert view.m1.tolist() == [False] * 4 + [True] + [False] * 4
    assert not view.collision.any()
    unflagged = red_pixels(np.asarray(_png(plot_trajectory(traj, every=4, eps=0.05, overlays=["m1"]))))
    ring = red_pixels(np.asarray(_png(plot_trajectory(traj, every=4, eps=0.2, overlays=["personal_space"]))))
    assert ring > unflagged + 100  # the same figure and legend, plus one red ring at sample 4


def test_collision_is_marked():
    traj = close_pass()
    pos = traj.positions.copy()
    pos[4:, 1, 0] = 0.3  # the human steps into the robot: overlap from sample 4 on
    hit = dataclasses.replace(traj, positions=pos, velocities=np.zeros_like(pos), outcome="collision")
    view = episode_view(hit)
    assert view.collision[:4].tolist() == [False] * 4 and view.collision[4]
    assert red_pixels(np.asarray(_png(plot_trajectory(hit)))) > 50


def _png(fig):
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    buf.seek(0)
    return Image.open(buf).convert("RGB")


def test_render_a_users_csv_file(tmp_path, capsys):
    path = tmp_path / "log.csv"
    a, b = close_pass(), close_pass()
    write_trajectories(path, [a, b])
    assert main(["render", str(path), "--episode", "1", "--out", str(tmp_path / "log.png"), "--quiet"]) == 0
    assert_not_blank(rgb(tmp_path / "log.png"))
    assert main(["render", str(path), "--out", str(tmp_path / "x.png")]) == 2
    assert "holds 2 episodes: pass --episode KEY (one of 0, 1)" in capsys.readouterr().err
    assert main(["render", str(path), "--episode", "7", "--out", str(tmp_path / "x.png")]) == 2
    assert "no episode '7'" in capsys.readouterr().err


def test_render_a_robot_log_of_another_layout_as_metrics_reads_it(tmp_path, capsys):
    rows = ["stamp,track,px,py"]  # the README's log layout: no role, no radius, other column names
    for k in range(12):
        rows += [f"{0.25 * k},0,0,{-1.5 + 0.25 * k}", f"{0.25 * k},1,0.8,{1.5 - 0.2 * k}"]
    path = tmp_path / "my_log.csv"
    path.write_text("\n".join(rows) + "\n")
    out = tmp_path / "log.png"
    argv = ["render", str(path), "--columns", "time=stamp,id=track,x=px,y=py", "--robot", "0",
            "--out", str(out)]
    assert main(argv) == 0
    assert_not_blank(rgb(out))
    err = capsys.readouterr().err
    assert "note: " in err and "assumed radius 0.3 m" in err and "Warning" not in err  # notes, as metrics
    assert "agent 0: no goals in the data; assumed the robot's goal (its last position)" in err
    assert main([*argv[:6], "--ego", "all", "--out", str(out)]) == 2
    assert "--ego all: render draws one episode; give one agent id" in capsys.readouterr().err


def test_bad_overlay_and_format_mismatch_are_clear(run_dir, capsys):
    assert main(["render", str(run_dir), "--episode", "passing/invisible/1", "--overlay", "m9"]) == 2
    assert "unknown overlay 'm9'; valid: personal_space" in capsys.readouterr().err
    assert (
        main(
            ["render", str(run_dir), "--episode", "passing/invisible/1", "--format", "gif", "--out", "a.png"]
        )
        == 2
    )
    assert "does not end in .gif" in capsys.readouterr().err
    assert parse_overlays(["m1,m2", "all"]) == ("personal_space", "velocity_rectangles", "side_preference",
                                                 "lidar")


@pytest.mark.parametrize(("extra", "message"), [
    (["--eps", "-1"], "--eps must be a finite number > 0, got -1.0"),
    (["--tau", "nan"], "--tau must be a finite number > 0, got nan"),
    (["--every", "-2"], "--every must be an integer >= 1, got -2"),
    (["--max-frames", "0"], "--max-frames must be an integer >= 1, got 0"),
    (["--out", "ep.jpg"], "--out ep.jpg: cannot write .jpg; formats: "),
    (["--out", "{tmp}/afile/r.png"], "afile is a file, not a directory"),
])
def test_render_options_that_make_no_sense_are_named(run_dir, tmp_path, capsys, extra, message):
    (tmp_path / "afile").write_text("")
    extra = [e.replace("{tmp}", str(tmp_path)) for e in extra]
    assert main(["render", str(run_dir), "--episode", "passing/invisible/1", *extra]) == 2
    assert message in capsys.readouterr().err


def test_frame_indices_hand_computed():
    assert frame_indices(5) == [0, 1, 2, 3, 4]
    assert frame_indices(10, stride=4) == [0, 4, 8, 9]
    assert frame_indices(101, max_frames=11) == list(range(0, 101, 10))


@given(st.integers(1, 2000), st.integers(1, 7), st.integers(2, 300))
def test_frame_indices_properties(n, stride, max_frames):
    idx = frame_indices(n, stride, max_frames)
    assert idx[0] == 0 and idx[-1] == n - 1
    assert all(b > a for a, b in zip(idx, idx[1:], strict=False))
    assert len(idx) <= max(max_frames, 1) + 1


def test_training_curves_figure(tmp_path):
    from socialnav.viz.figures import read_curves, save_figure, training_curves

    rows = read_curves(ROOT / "benchmarks" / "results" / "train_crowdnav_sarl_s0_curves.csv")
    paths = save_figure(training_curves(rows), tmp_path / "curves")
    assert [p.suffix for p in paths] == [".png", ".svg"]
    assert_not_blank(rgb(paths[0]))
    with pytest.raises(ValueError, match="not a curves.csv"):
        (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
        read_curves(tmp_path / "bad.csv")


def test_ppo_training_curves_figure_and_report(tmp_path):
    """A PPO run's curves (phase ppo, env_steps) are drawn against environment steps, also in the report
    of an evaluation whose checkpoint has its curves.csv beside it."""
    import shutil

    from socialnav.cli import main
    from socialnav.policies.building import shipped_checkpoint
    from socialnav.viz.figures import read_curves, training_curves

    curves = ROOT / "benchmarks" / "results" / "train_wang2022_crowdnav_pp_s0_curves.csv"
    fig = training_curves(read_curves(curves))
    ax1, ax2 = fig.axes
    assert ax1.get_xlabel() == "environment steps" and ax2.get_ylabel() == "value loss"
    assert len(ax1.lines) == 4 and len(ax2.lines) == 1  # train/val success and collision; the value loss
    run = tmp_path / "train"
    run.mkdir()
    shutil.copy(shipped_checkpoint("crowdnav_pp", "wang2022"), run / "best.pt")
    shutil.copy(curves, run / "curves.csv")
    out = tmp_path / "eval"
    assert main(["evaluate", "--policy", "crowdnav_pp", "--checkpoint", str(run / "best.pt"), "--scenario",
                 "passing", "--episodes", "2", "--out", str(out), "--report", "--no-progress"]) == 0
    assert f"Training curves: {run / 'curves.csv'}" in (out / "report.html").read_text()


def test_env_rgb_array_rendering():
    import gymnasium as gym

    import socialnav.envs.registration  # noqa: F401

    env = gym.make("socialnav/CircleCrossing-v0", render_mode="rgb_array")
    env.reset(seed=3)
    first = env.render()
    assert first.shape == (480, 480, 3) and first.dtype == np.uint8
    assert_not_blank(first)
    for _ in range(6):
        *_, terminated, truncated, _ = env.step(np.array([0.0, 1.0]))
        if terminated or truncated:  # stepping an ended episode is an error (reset first)
            break
    assert np.mean(env.render() != first) > 0.005
    env.close()


def test_env_rendering_draws_the_episodes_walls():
    import gymnasium as gym

    import socialnav.envs.registration  # noqa: F401
    from socialnav.scenarios import make_scenario
    from socialnav.trajectory import Trajectory

    env = gym.make("socialnav/CircleCrossing-v0", scenario="blind_corner", render_mode="rgb_array",
                   split="test")
    env.reset(options={"index": 0})
    frame = env.render()
    recorder = env.unwrapped._recorder
    drawn = recorder.trajectory()
    walls = make_scenario("blind_corner").episodes("test", [0]).static_map(0)
    assert drawn.static_map is not None and drawn.static_map.edges()[0].tolist() == walls.edges()[0].tolist()
    bare = Trajectory.from_positions(np.stack(recorder.positions), drawn.dt, radii=drawn.radii,
                                     v_pref=drawn.v_pref, goals=drawn.goals)
    assert np.mean(recorder.viewer().frame(bare) != frame) > 0.002  # the walls are in the picture
    env.close()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="displays are detected by DISPLAY on Linux")
def test_env_human_mode_without_display_is_a_clear_error(monkeypatch):
    from socialnav.envs.single import SocialNavEnv

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(RuntimeError, match="needs a display"):
        SocialNavEnv(render_mode="human")
    with pytest.raises(ValueError, match="render_mode must be one of rgb_array, human"):
        SocialNavEnv(render_mode="video")


def test_html_page_of_one_episode(run_dir, tmp_path, capsys):
    import json
    import re

    out = tmp_path / "ep.html"
    assert (
        main(["render", str(run_dir), "--episode", "passing/invisible/2", "--out", str(out), "--quiet"]) == 0
    )
    text = out.read_text()
    data = json.loads(
        re.search(r'type="application/json">(.*?)</script>', text, re.S).group(1).replace("<\\/", "</")
    )
    assert [e["id"] for e in data["episodes"]] == ["passing/invisible/2"]
    assert data["episodes"][0]["side"][1] in ("left", "right", "unlabelled")
    assert "<script src" not in text and "viewer-canvas" in text
    # the page's viewer switches its own overlays: an --overlay would be dropped, so it is refused
    assert main(["render", str(run_dir), "--episode", "passing/invisible/2", "--out",
                 str(tmp_path / "l.html"), "--overlay", "lidar", "--quiet"]) == 2
    assert "--overlay lidar: the html page draws no --overlay" in capsys.readouterr().err
    assert not (tmp_path / "l.html").exists()


def test_a_log_without_radii_renders_as_metrics_scores_it(tmp_path, capsys):
    """A long-format log without a radius column: `socialnav metrics` scores it with the assumed
    0.3 m and says so; `socialnav render` draws it the same way instead of refusing it."""
    import pyarrow.csv as pcsv

    path = tmp_path / "log.csv"
    write_trajectories(path, [close_pass()])
    table = pcsv.read_csv(path)
    pcsv.write_csv(table.drop_columns(["radius", "settings"]), path)
    assert main(["metrics", str(path), "--json"]) in (0, 1)
    assert "assumed radius 0.3" in capsys.readouterr().out
    assert main(["render", str(path), "--out", str(tmp_path / "log.png"), "--quiet"]) == 0
    assert_not_blank(rgb(tmp_path / "log.png"))
