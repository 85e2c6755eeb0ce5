"""End to end: the `socialnav train` CLI on tiny settings, evaluation of its checkpoint, resumption,
and divergence handling."""

import csv
import dataclasses
import json

import pytest
import torch

import socialnav.train.value.rl_phase as rl_phase
from socialnav.cli import main
from socialnav.policies.learned import load_checkpoint
from socialnav.train.optim import TrainingDiverged
from socialnav.train.value.settings import load_train_settings
from socialnav.train.value.trainer import train

TINY = """\
collection_batch: 8
threads: 1
checkpoint_every: 8
log_every: 4
imitation: {episodes: 8, epochs: 1}
rl: {episodes: 24, validate_every: 12, val_episodes: 4, target_update_every: 8, warmup_transitions: 50,
     gradient_steps_per_episode: 1, epsilon_decay_episodes: 20}
"""


@pytest.fixture()
def tiny(tmp_path):
    p = tmp_path / "tiny.yaml"
    p.write_text(TINY)
    return p


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_cli_train_then_evaluate(tmp_path, tiny, quick_preset, capsys):
    out = tmp_path / "run"
    rc = main(
        [
            "train",
            "--policy",
            "sarl",
            "--preset",
            quick_preset,
            "--out",
            str(out),
            "--seed",
            "0",
            "--config",
            str(tiny),
            "--no-progress",
        ]
    )
    assert rc == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["episodes"] >= 24 and summary["resumed"] is False
    for name in ("best.pt", "last.pt", "il.pt", "curves.csv", "config.yaml", "config.json"):
        assert (out / name).exists(), name
    config = json.loads((out / "config.json").read_text())
    assert config["train"]["seed"] == 0 and config["preset"]["name"] == "crowdnav_quick"
    assert set(config["seeds"]) == {"scenario_start", "exploration", "init", "sampling"}
    ck = load_checkpoint(out / "best.pt", "sarl")
    vp = ck.config["value_policy"]
    assert set(vp) == {
        "kinematics",
        "gamma",
        "information",
        "rotation_limit",
        "dt",
        "reward",
        "planning_depth",
        "planning_width",
        "reward_rule",
    }
    assert (vp["information"], vp["planning_depth"], vp["reward_rule"]) == ("constant_velocity", 1, "end")
    assert set(vp["reward"]) == {
        "success_reward",
        "collision_penalty",
        "discomfort_dist",
        "discomfort_penalty_factor",
        "time_step",
    }
    rows = _rows(out / "curves.csv")
    assert rows[0]["phase"] == "il" and rows[0]["val_success"] != ""
    rl_rows = [r for r in rows if r["phase"] == "rl"]
    assert rl_rows and int(rl_rows[-1]["episode"]) >= 24
    assert any(r["val_success"] != "" for r in rl_rows)
    assert float(rl_rows[0]["epsilon"]) == pytest.approx(0.5, abs=0.05)
    # the evaluator loads the trained checkpoint
    ev = tmp_path / "eval"
    rc = main(
        [
            "evaluate",
            "--policy",
            "sarl",
            "--checkpoint",
            str(out / "best.pt"),
            "--preset",
            "crowdnav",
            "--episodes",
            "20",
            "--out",
            str(ev),
            "--no-progress",
            "--json",
        ]
    )
    assert rc == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["rows"]
    assert (ev / "summary.json").exists()
    # a training run and an evaluation never share a directory, either way round
    argv = ["train", "--policy", "sarl", "--preset", quick_preset, "--config", str(tiny), "--no-progress"]
    assert main([*argv, "--out", str(ev)]) == 2
    assert f"{ev} holds the results of an evaluation of one policy (manifest.json)" in capsys.readouterr().err
    assert not (ev / "curves.csv").exists()
    evaluate = ["evaluate", "--policy", "orca", "--episodes", "1", "--scenario", "passing", "--no-progress"]
    assert main([*evaluate, "--out", str(out)]) == 2
    assert f"{out} holds the results of a training run (`socialnav train`) (curves.csv)" in (
        capsys.readouterr().err)
    assert not (out / "manifest.json").exists()


def test_imitation_diverging_in_its_first_epoch_names_no_file_it_did_not_write(tmp_path, tiny):
    settings = load_train_settings(tiny)
    settings = dataclasses.replace(settings, imitation=dataclasses.replace(
        settings.imitation, episodes=8, epochs=3, lr=1e30, batch_size=4))  # NaN within the first epoch
    with pytest.raises(TrainingDiverged, match=r"in epoch 0; no epoch finished \(lower imitation.lr\?\)"):
        train("sarl", "crowdnav", tmp_path / "run", settings, progress=False, log=lambda _: None)
    assert not (tmp_path / "run" / "il_state.pt").exists()


def test_resume_continues_counters(tmp_path, tiny, quick_preset):
    out = tmp_path / "run"
    settings = load_train_settings(tiny)
    first = train("sarl", quick_preset, out, settings, progress=False, stop_after=12)  # "killed" after 12
    assert not first.finished and first.episodes < 24
    ck = torch.load(out / "last.pt", weights_only=True)
    saved = ck["extra"]["resume"]
    assert 8 <= saved["episode"] <= first.episodes
    assert saved["gradient_steps"] > 0
    second = train("sarl", quick_preset, out, settings, progress=False)
    assert second.resumed and second.finished
    assert second.episodes >= 24
    assert second.gradient_steps > saved["gradient_steps"]
    final = torch.load(out / "last.pt", weights_only=True)["extra"]["resume"]
    assert final["episode"] == second.episodes
    rows = [r for r in _rows(out / "curves.csv") if r["phase"] == "rl"]
    episodes = [int(r["episode"]) for r in rows]
    assert episodes == sorted(episodes)  # rows after the resumed checkpoint were replaced, not duplicated
    assert len([r for r in _rows(out / "curves.csv") if r["phase"] == "il"]) == 1
    # the budget may not fall below the episodes done (the record would then say 10 of a 24-episode run)
    shorter = dataclasses.replace(settings, rl=dataclasses.replace(settings.rl, episodes=10))
    below = f"rl.episodes 10 is below the {second.episodes} RL episodes this run has done"
    with pytest.raises(ValueError, match=below):
        train("sarl", quick_preset, out, shorter, progress=False)
    assert load_checkpoint(out / "last.pt", "sarl").config["train"]["rl"]["episodes"] == 24
    # resuming with different settings is refused, naming the key
    other = load_train_settings(tiny, seed=5)
    with pytest.raises(ValueError, match="train.seed"):
        train("sarl", quick_preset, out, other, progress=False)


def test_nan_loss_stops_and_keeps_last_good_checkpoint(tmp_path, tiny, quick_preset, monkeypatch):
    out = tmp_path / "run"
    settings = load_train_settings(tiny)
    real = rl_phase.replay_td_loss
    calls = {"n": 0}

    def flaky(*args, **kwargs):
        loss_at = real(*args, **kwargs)

        def loss(idx):
            calls["n"] += 1
            value = loss_at(idx)
            return value * float("nan") if calls["n"] > 10 else value

        return loss

    monkeypatch.setattr(rl_phase, "replay_td_loss", flaky)
    with pytest.raises(TrainingDiverged, match="nan"):
        train("sarl", quick_preset, out, settings, progress=False)
    ck = load_checkpoint(out / "last.pt", "sarl")
    assert all(torch.isfinite(v).all() for v in ck.model.state_dict().values())
    assert ck.extra["resume"]["gradient_steps"] <= 10
    assert load_checkpoint(out / "best.pt", "sarl")
    # through the CLI: one clear error line, exit status 2
    def always_nan(*args, **kwargs):
        loss_at = real(*args, **kwargs)
        return lambda idx: loss_at(idx) * float("nan")

    monkeypatch.setattr(rl_phase, "replay_td_loss", always_nan)
    rc = main(
        [
            "train",
            "--policy",
            "sarl",
            "--preset",
            quick_preset,
            "--out",
            str(tmp_path / "run2"),
            "--config",
            str(tiny),
            "--no-progress",
        ]
    )
    assert rc == 2


def test_cadrl_trains_with_one_human(tmp_path, tiny):
    settings = load_train_settings(tiny)
    import dataclasses

    settings = dataclasses.replace(
        settings, rl=dataclasses.replace(settings.rl, episodes=4, validate_every=4)
    )
    res = train("cadrl", "wang2022", tmp_path / "c", settings, progress=False)
    config = json.loads((tmp_path / "c" / "config.json").read_text())
    assert config["n_humans"] == 1 and res.finished


def test_a_resume_that_would_end_before_best_pts_episode_is_refused(tmp_path, tiny, quick_preset,
                                                                     monkeypatch):
    # a validation after the last last.pt found a new best, then the run was killed: best.pt is ahead
    from socialnav.settings import ConfigError

    out = tmp_path / "run"
    settings = dataclasses.replace(load_train_settings(tiny), checkpoint_every=100)  # last.pt: episode 0
    monkeypatch.setattr(rl_phase, "better", lambda new, old: True)  # every validation is a new best
    train("sarl", quick_preset, out, settings, progress=False, stop_after=12)
    resumed_at = torch.load(out / "last.pt", weights_only=True)["extra"]["resume"]["episode"]
    best_at = load_checkpoint(out / "best.pt", "sarl").extra["episode"]
    assert resumed_at < best_at
    short = dataclasses.replace(settings, rl=dataclasses.replace(settings.rl, episodes=best_at - 1))
    with pytest.raises(ConfigError, match=f"best.pt holds the network of the validation at RL episode "
                                          f"{best_at}, written after last.pt \\(episode {resumed_at}\\)"):
        train("sarl", quick_preset, out, short, progress=False)
    # the full budget: the resumed run gets there again, and best.pt and the reported best agree
    result = train("sarl", quick_preset, out, settings, progress=False)
    assert result.finished
    assert load_checkpoint(out / "best.pt", "sarl").extra["episode"] == result.best_val["episode"] >= best_at


def test_damaged_curve_rows_do_not_block_resume(tmp_path, tiny, quick_preset):
    out = tmp_path / "run"
    settings = load_train_settings(tiny)
    train("sarl", quick_preset, out, settings, progress=False, stop_after=12)
    with open(out / "curves.csv", "a") as f:  # a row cut short by a kill, and garbage
        f.write("rl,1\n\x00\x01garbage\nrl,notanumber,0.5,,,,,,,,,,,,\n")
    (out / ".last.pt.abc123.tmp").write_bytes(b"half a checkpoint")  # left by a writer killed mid-write
    lines = []
    second = train("sarl", quick_preset, out, settings, progress=False, log=lines.append)
    assert second.resumed and second.finished
    assert any("3 damaged row(s) left out" in line for line in lines), lines
    assert f"training sarl under preset 'crowdnav_quick' on cpu into {out}" in lines  # the device used
    rows = _rows(out / "curves.csv")
    assert all(r["phase"] in ("il", "rl") and r["episode"].isdigit() for r in rows)
    assert not list(out.glob(".*.tmp"))


def test_mp_rgl_trains_its_predictor_in_the_same_resumable_run(tmp_path, tiny, quick_preset, capsys):
    from socialnav.policies.learned_loading import load_learned_policy

    out = tmp_path / "mp"
    settings = load_train_settings(tiny)
    first = train("mp_rgl", quick_preset, out, settings, progress=False, stop_after=12)
    assert not first.finished
    il = load_checkpoint(out / "il.pt", "mp_rgl")
    assert il.predictor is not None
    assert il.config["train"]["information"] == "learned"
    assert (il.config["value_policy"]["planning_depth"], il.config["value_policy"]["planning_width"]) == (
        2,
        2,
    )
    saved = torch.load(out / "last.pt", weights_only=True)
    assert saved["predictor"] is not None and "predictor_optimizer" in saved["extra"]["resume"]
    second = train("mp_rgl", quick_preset, out, settings, progress=False)
    assert second.resumed and second.finished
    last = load_checkpoint(out / "last.pt", "mp_rgl")
    moved = any(
        not torch.equal(last.predictor.state_dict()[k], v)
        for k, v in saved["predictor"]["state_dict"].items()
    )
    assert moved  # the predictor kept learning during RL, from its saved state
    rows = _rows(out / "curves.csv")
    assert any(r["predictor_loss"] for r in rows if r["phase"] == "rl")
    policy = load_learned_policy("mp_rgl", out / "best.pt")
    assert policy.describe()["information"] == "learned" and policy.value_policy.planning_depth == 2
    # the command line evaluates it, and its d = 1 variant
    ev = tmp_path / "ev"
    args = ["evaluate", "--policy", "mp_rgl", "--checkpoint", str(out / "best.pt"), "--preset", quick_preset]
    args += ["--scenario", "circle_crossing", "--episodes", "2", "--no-progress", "--json", "--out", str(ev)]
    assert main([*args, "--planning-depth", "1"]) == 0
    manifest = json.loads((ev / "manifest.json").read_text())
    assert manifest["policy"]["planning_depth"] == 1
    # a SARL checkpoint has no predictor: 'learned' is refused with a clear message
    sarl = tmp_path / "sarl"
    train("sarl", quick_preset, sarl, load_train_settings(tiny), progress=False)
    capsys.readouterr()
    code = main(
        [
            "evaluate",
            "--policy",
            "sarl",
            "--checkpoint",
            str(sarl / "best.pt"),
            "--preset",
            quick_preset,
            "--information",
            "learned",
            "--episodes",
            "1",
            "--scenario",
            "circle_crossing",
            "--out",
            str(tmp_path / "ev2"),
            "--no-progress",
        ]
    )
    assert code == 2
    assert "stores no state predictor" in capsys.readouterr().err
