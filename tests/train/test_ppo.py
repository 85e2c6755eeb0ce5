"""PPO: GAE and the clipped loss against hand-computed values, learning a trivial task, bit-identical
resumption, settings validation and the CLI end to end."""

import csv
import dataclasses
import json
import math
from importlib import resources

import numpy as np
import pytest
import torch
import yaml

from socialnav.settings import ConfigError
from socialnav.train.ppo.algorithm import gae
from socialnav.train.ppo.loss import gaussian_entropy, gaussian_log_prob, ppo_loss
from socialnav.train.ppo.settings import NetworkSettings, PPOSettings, load_ppo_settings
from tests.learned.helpers import SMALL_ATTN_GRAPH

SMALL = NetworkSettings(**SMALL_ATTN_GRAPH)


def test_gae_matches_hand_computed_values():
    # γ = 0.9, λ = 0.8; the episode ends with step 1, so step 1 is not bootstrapped and does not
    # pass step 2's advantage back.
    rewards = torch.tensor([[1.0], [0.0], [2.0]])
    values = torch.tensor([[0.5], [0.4], [0.3]])
    dones = torch.tensor([[False], [True], [False]])
    adv, ret = gae(rewards, values, dones, torch.tensor([1.0]), gamma=0.9, lam=0.8)
    # δ2 = 2 + 0.9·1.0 − 0.3 = 2.6;  δ1 = 0 − 0.4 = −0.4;  δ0 = 1 + 0.9·0.4 − 0.5 = 0.86
    # A0 = 0.86 + 0.9·0.8·(−0.4) = 0.572
    assert adv[:, 0].tolist() == pytest.approx([0.572, -0.4, 2.6], abs=1e-6)
    assert ret[:, 0].tolist() == pytest.approx([1.072, 0.0, 2.9], abs=1e-6)


def test_gae_with_lambda_one_and_no_done_is_the_discounted_return():
    rewards = torch.tensor([[1.0], [1.0]])
    values = torch.tensor([[0.0], [0.0]])
    _, ret = gae(
        rewards, values, torch.zeros(2, 1, dtype=torch.bool), torch.tensor([10.0]), gamma=0.5, lam=1.0
    )
    assert ret[:, 0].tolist() == pytest.approx([1 + 0.5 + 0.25 * 10, 1 + 0.5 * 10])


def _loss(value_clip, normalize=False):
    return ppo_loss(
        torch.log(torch.tensor([1.5, 0.5])),
        torch.zeros(2),
        torch.tensor([1.0, -2.0]),
        torch.tensor([1.0, 0.0]),
        torch.tensor([0.5, 0.5]),
        torch.tensor([2.0, 0.0]),
        torch.tensor([1.0, 1.0]),
        clip=0.2,
        value_clip=value_clip,
        value_coef=0.5,
        entropy_coef=0.01,
        normalize_advantages=normalize,
    )


def test_ppo_loss_matches_hand_computed_values():
    loss = _loss(0.2)
    # ratios 1.5 and 0.5: max(−1·1.5, −1·1.2) = −1.2 and max(2·0.5, 2·0.8) = 1.6 → L_π = 0.2
    assert float(loss.policy) == pytest.approx(0.2)
    # value clipping: max((1−2)², (0.7−2)²) = 1.69 and max(0², 0.3²) = 0.09 → ½·mean = 0.445
    assert float(loss.value) == pytest.approx(0.445)
    assert float(loss.total) == pytest.approx(0.2 + 0.5 * 0.445 - 0.01 * 1.0)
    assert float(loss.clip_fraction) == 1.0
    kl = ((0.5 - math.log(1.5)) + (-0.5 - math.log(0.5))) / 2
    assert float(loss.approx_kl) == pytest.approx(kl)
    assert float(_loss(None).value) == pytest.approx(0.25)  # ½·mean((1−2)², 0²)


def test_ppo_loss_normalises_advantages_per_minibatch():
    # A = [1, −2] → ±1/√2 (std with Bessel's correction): max(−1.5/√2, −1.2/√2) = −1.2/√2 and
    # max(0.5/√2, 0.8/√2) = 0.8/√2
    assert float(_loss(0.2, normalize=True).policy) == pytest.approx(
        (-1.2 + 0.8) / 2 / math.sqrt(2), rel=1e-6
    )


def test_gaussian_log_prob_and_entropy_match_torch_distributions():
    mean, log_std = torch.tensor([[0.3, -1.0]]), torch.tensor([0.2, -0.5])
    x = torch.tensor([[1.0, 0.5]])
    ref = torch.distributions.Normal(mean, log_std.exp())
    assert float(gaussian_log_prob(x, mean, log_std)) == pytest.approx(float(ref.log_prob(x).sum()))
    assert float(gaussian_entropy(log_std)) == pytest.approx(float(ref.entropy().sum()))


def test_settings_errors_name_field_and_value(tmp_path):
    with pytest.raises(ConfigError, match="clip"):
        PPOSettings(clip=1.5)
    with pytest.raises(ConfigError, match="network.attn_size"):
        NetworkSettings(attn_size=30, attn_heads=8)
    bad = tmp_path / "bad.yaml"
    bad.write_text("n_envs: 8\nrolout_steps: 4\n")
    with pytest.raises(ConfigError, match="rolout_steps"):
        load_ppo_settings(bad)
    assert load_ppo_settings("ppo_smoke").total_env_steps == 256
    assert load_ppo_settings("ppo_repo").network == NetworkSettings()  # the repository's sizes
    assert load_ppo_settings("ppo").network.attn_size == 64


def _tiny(**settings) -> PPOSettings:
    """A few tiny updates of the small network on one thread (validation rare unless given)."""
    defaults = {"validate_every": 10, "val_episodes": 2, "threads": 1, "network": SMALL}
    return PPOSettings(**{**defaults, **settings})


@pytest.fixture()
def empty_preset(tmp_path):
    """wang2022 without humans and a 10 s time limit: the robot has only to reach its goal."""
    data = yaml.safe_load((resources.files("socialnav.configs") / "wang2022.yaml").read_text())
    data["name"] = "empty"
    data["world"]["time_limit"] = 10.0
    data["training"]["n_humans"] = 0
    p = tmp_path / "empty.yaml"
    p.write_text(yaml.safe_dump(data))
    return str(p)


def test_ppo_learns_to_reach_the_goal_without_humans(tmp_path, empty_preset):
    from socialnav.train.ppo.algorithm import train_ppo

    s = PPOSettings(
        n_envs=32,
        rollout_steps=16,
        total_env_steps=16384,
        epochs=4,
        minibatches=2,
        lr=1e-3,
        validate_every=8,
        val_episodes=16,
        checkpoint_every=100,
        threads=1,
        network=SMALL,
    )
    result = train_ppo(empty_preset, tmp_path / "run", s, progress=False, log=lambda _: None)
    assert result.finished and result.updates == 32 and result.env_steps == 16384
    rows = list(csv.DictReader(open(result.curves)))
    first_val = next(r for r in rows if r["val_success"])
    last_val = [r for r in rows if r["val_success"]][-1]
    assert float(first_val["val_success"]) == 0.0  # the untrained policy does not get there
    assert float(last_val["val_success"]) >= 0.9  # 16 deterministic validation episodes


def _curve_rows(path):
    return [
        {k: v for k, v in r.items() if k not in ("wall_time", "env_steps_per_s")}
        for r in csv.DictReader(open(path))
    ]


def test_validation_does_not_change_what_is_trained(tmp_path):
    """The default schedule validates on 1 000 episodes to choose best.pt; the training itself (the network
    after every update) is the same whatever the validation's size and period, so a seed trained with
    another validation differs only in the checkpoint it chose (docs/ppo.md)."""
    from socialnav.policies.learned import load_checkpoint
    from socialnav.train.ppo.algorithm import train_ppo

    s = _tiny(n_envs=8, rollout_steps=8, total_env_steps=8 * 8 * 4, epochs=2, minibatches=2,
              checkpoint_every=5)
    runs = {}
    for name, every, episodes in (("rare", 4, 2), ("often", 1, 12)):
        out = tmp_path / name
        train_ppo("wang2022", out, dataclasses.replace(s, validate_every=every, val_episodes=episodes),
                  progress=False, log=lambda _: None)
        runs[name] = load_checkpoint(out / "last.pt", "crowdnav_pp", -1).model.state_dict()
        validated = [r for r in _curve_rows(out / "curves.csv") if r["val_success"]]
        assert len(validated) == 4 // every
    for key, value in runs["rare"].items():
        assert torch.equal(value, runs["often"][key]), key
    assert load_ppo_settings("ppo").val_episodes == 1000


def test_a_resumed_budget_may_not_fall_below_the_updates_done_and_an_extension_says_its_lr(tmp_path):
    from socialnav.train.ppo.algorithm import train_ppo

    s = _tiny(n_envs=4, rollout_steps=4, total_env_steps=4 * 4 * 3, epochs=1, minibatches=1,
              checkpoint_every=1)
    train_ppo("wang2022", tmp_path / "run", s, progress=False, log=lambda _: None)  # 3 updates
    shorter = dataclasses.replace(s, total_env_steps=4 * 4 * 2)
    below = r"total_env_steps 32 \(2 updates\) is below the 3 updates this run has done \(total_env_steps 48"
    with pytest.raises(ValueError, match=below):
        train_ppo("wang2022", tmp_path / "run", shorter, progress=False, log=lambda _: None)
    lines: list[str] = []
    longer = dataclasses.replace(s, total_env_steps=4 * 4 * 6)
    result = train_ppo("wang2022", tmp_path / "run", longer, progress=False, log=lines.append)
    assert result.updates == 6
    lr = s.lr * (1 - 3 / 6)  # the new schedule at update 3; the old one had reached 0 there
    said = (f"total_env_steps 48 -> 96: with anneal_lr the learning rate decays to 0 over the new budget "
            f"from update 3 on ({lr:.3g} there, not 0): the run follows neither schedule throughout")
    assert said in lines, lines


def test_a_run_killed_before_its_first_checkpoint_is_not_overwritten_by_another(tmp_path):
    import shutil

    from socialnav.train.ppo.algorithm import train_ppo
    from socialnav.train.value.settings import load_train_settings
    from socialnav.train.value.trainer import train

    s = _tiny(n_envs=4, rollout_steps=4, total_env_steps=4 * 4, epochs=1, minibatches=1)
    train_ppo("wang2022", tmp_path / "done", s, progress=False, log=lambda _: None)
    killed = tmp_path / "killed"  # what a run killed before its first last.pt leaves: its record
    killed.mkdir()
    shutil.copy(tmp_path / "done" / "config.json", killed / "config.json")
    other = rf"{killed} holds a run of the 'ppo' trainer \(policy 'crowdnav_pp'\), and 'sarl' trains with the"
    with pytest.raises(ValueError, match=other):
        train("sarl", "wang2022", killed, load_train_settings("smoke"), progress=False, log=lambda _: None)
    with pytest.raises(ValueError, match=r"train.seed: 0 -> 1"):
        train_ppo("wang2022", killed, dataclasses.replace(s, seed=1), progress=False, log=lambda _: None)
    assert json.loads((killed / "config.json").read_text())["policy"] == "crowdnav_pp"  # untouched
    assert train_ppo("wang2022", killed, s, progress=False, log=lambda _: None).finished  # its own settings


def test_resumed_run_equals_an_uninterrupted_one_bit_for_bit(tmp_path):
    from socialnav.policies.learned import load_checkpoint
    from socialnav.train.ppo.algorithm import train_ppo

    # 5 humans, 30 s episodes: the stop falls in the middle of episodes, whose state is restored.
    s = _tiny(n_envs=8, rollout_steps=8, total_env_steps=8 * 8 * 6, epochs=2, minibatches=2,
              validate_every=4, val_episodes=4, checkpoint_every=5)
    whole = train_ppo("wang2022", tmp_path / "whole", s, progress=False, log=lambda _: None)
    first = train_ppo("wang2022", tmp_path / "split", s, progress=False, stop_after=3, log=lambda _: None)
    assert not first.finished and first.updates == 3
    lines: list[str] = []
    second = train_ppo("wang2022", tmp_path / "split", s, progress=False, log=lines.append)
    assert second.resumed and second.finished and second.updates == 6
    split = tmp_path / "split"
    assert lines[:2] == [f"resuming {split} at update 3 ({8 * 8 * 3} env steps)",
                         f"training crowdnav_pp under preset 'wang2022' on cpu into {split}"]
    a = load_checkpoint(whole.last_checkpoint, "crowdnav_pp", -1)
    b = load_checkpoint(second.last_checkpoint, "crowdnav_pp", -1)
    for key, value in a.model.state_dict().items():
        assert torch.equal(value, b.model.state_dict()[key]), key
    ra, rb = a.extra["resume"], b.extra["resume"]
    assert torch.equal(ra["h"], rb["h"])
    for wa, wb in zip(ra["worlds"], rb["worlds"], strict=True):
        for k in wa:
            if k != "next_index":  # NaN (no arrival yet) equals NaN here
                torch.testing.assert_close(wa[k], wb[k], rtol=0, atol=0, equal_nan=True, msg=k)
        assert wa["next_index"] == wb["next_index"]
    assert _curve_rows(whole.curves) == _curve_rows(second.curves)
    assert ra["episodes"] == rb["episodes"]


def test_resume_with_other_settings_is_refused(tmp_path):
    from socialnav.train.ppo.algorithm import train_ppo

    s = _tiny(n_envs=4, rollout_steps=4, total_env_steps=32, epochs=1, minibatches=1)
    train_ppo("wang2022", tmp_path / "run", s, progress=False, stop_after=1, log=lambda _: None)
    with pytest.raises(ConfigError, match="train.lr"):
        train_ppo("wang2022", tmp_path / "run", PPOSettings(**{**s.__dict__, "lr": 1e-2}), progress=False)


def test_first_gradient_step_starts_from_the_collecting_policy(tmp_path):
    """The rollout is re-evaluated with the network (and observation statistics) that collected it:
    with one epoch of one minibatch, the only gradient step sees probability ratios of 1."""
    from socialnav.train.ppo.algorithm import train_ppo

    s = _tiny(n_envs=8, rollout_steps=6, total_env_steps=8 * 6 * 2, epochs=1, minibatches=1)
    result = train_ppo("wang2022", tmp_path / "run", s, progress=False, log=lambda _: None)
    rows = list(csv.DictReader(open(result.curves)))
    assert len(rows) == 2
    for row in rows:
        assert abs(float(row["approx_kl"])) < 1e-6 and float(row["clip_fraction"]) == 0.0


def test_value_trainer_refuses_the_ppo_policy(tmp_path):
    from socialnav.train.value.trainer import train

    with pytest.raises(ValueError, match="PPO"):
        train("crowdnav_pp", "wang2022", tmp_path / "x")


def test_cli_train_then_evaluate(tmp_path, capsys):
    from socialnav.cli import main

    out = tmp_path / "run"
    assert (
        main(
            ["train", "--policy", "crowdnav_pp", "--config", "ppo_smoke", "--out", str(out), "--no-progress"]
        )
        == 0
    )
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["updates"] == 4 and summary["env_steps"] == 256
    for name in ("best.pt", "last.pt", "curves.csv", "config.yaml"):
        assert (out / name).is_file()
    rows = list(csv.DictReader(open(out / "curves.csv")))
    assert [int(r["update"]) for r in rows] == [1, 2, 3, 4] and all(r["phase"] == "ppo" for r in rows)
    # re-running the finished command resumes and does nothing more
    assert (
        main(
            ["train", "--policy", "crowdnav_pp", "--config", "ppo_smoke", "--out", str(out), "--no-progress"]
        )
        == 0
    )
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["resumed"] is True
    ev = tmp_path / "eval"
    assert (
        main(
            [
                "evaluate",
                "--policy",
                "crowdnav_pp",
                "--checkpoint",
                str(out / "best.pt"),
                "--preset",
                "wang2022",
                "--episodes",
                "2",
                "--out",
                str(ev),
            ]
        )
        == 0
    )
    assert (ev / "summary.json").is_file()


def test_cli_refuses_value_based_options_for_ppo(tmp_path, capsys):
    from socialnav.cli import main

    assert main(["train", "--policy", "crowdnav_pp", "--rl-episodes", "5", "--out", str(tmp_path / "r")]) == 2
    said = capsys.readouterr().err
    assert "--rl-episodes: not a setting of the PPO trainer of 'crowdnav_pp' (docs/ppo.md)" in said
    assert not (tmp_path / "r").exists()
    assert main(["train", "--policy", "sarl", "--env-steps", "5", "--out", str(tmp_path / "r")]) == 2
    assert "--env-steps" in capsys.readouterr().err


def test_squashed_actions_stay_in_the_action_set():
    from socialnav.policies.learned.attn_graph import squash_actions

    raw = np.array([[3.0, 4.0], [0.3, -0.4], [-2.0, 9.0]])
    hol = squash_actions(raw, "holonomic", np.array([1.0, 1.0, 1.5]), math.pi / 4)
    assert hol[0].tolist() == pytest.approx([0.6, 0.8]) and hol[1].tolist() == [0.3, -0.4]
    assert np.hypot(*hol[2]) == pytest.approx(1.5)
    # a unicycle's sample, clipped to [-1, 1], spans v in [0, v_pref] and dθ in ±rotation_limit
    uni = squash_actions(raw, "unicycle", np.array([1.0, 1.0, 1.5]), math.pi / 4)
    np.testing.assert_allclose(uni, [[1.0, math.pi / 4], [0.65, -0.1 * math.pi], [0.0, math.pi / 4]])
    assert squash_actions(np.zeros((1, 2)), "unicycle", np.array([1.2]), 1.0).tolist() == [[0.6, 0.0]]
    # the older unicycle squash, which records without action_squash load with
    clip = squash_actions(raw, "unicycle", np.array([1.0, 1.0, 1.5]), math.pi / 4, squash="clip")
    np.testing.assert_allclose(clip, [[1.0, math.pi / 4], [0.3, -0.4], [0.0, math.pi / 4]])


def test_a_records_action_squash_reads_old_unicycle_records_as_clipped():
    from socialnav.policies.learned.attn_graph import recorded_action_squash
    from socialnav.presets import load_preset
    from socialnav.train.worlds import ppo_policy_config

    new = ppo_policy_config(load_preset("wang2022_unicycle"))
    assert new["action_squash"] == "span" and recorded_action_squash("unicycle", new) == "span"
    assert recorded_action_squash("unicycle", {}) == "clip"
    # holonomic and differential-drive records are as before (their shipped checkpoints unchanged)
    assert "action_squash" not in ppo_policy_config(load_preset("wang2022"))
    assert "action_squash" not in ppo_policy_config(load_preset("wang2022_diffdrive"))
    assert recorded_action_squash("holonomic", {}) == "radial"
    assert recorded_action_squash("diff_drive", {}) == "span"
    with pytest.raises(ValueError, match="action_squash 'clip' is not one for a diff_drive robot"):
        recorded_action_squash("diff_drive", {"action_squash": "clip"})


def test_cuda_device_is_refused_clearly_without_a_gpu(tmp_path, capsys):
    from socialnav.cli import main

    if torch.cuda.is_available():
        pytest.skip("a GPU is present: test_ppo_trains_on_cuda covers it")
    args = [
        "train",
        "--policy",
        "crowdnav_pp",
        "--config",
        "ppo_smoke",
        "--device",
        "cuda",
        "--out",
        str(tmp_path / "r"),
    ]
    assert main(args) == 2
    assert "device 'cuda' requested but torch.cuda.is_available() is False" in capsys.readouterr().err
    assert not (tmp_path / "r").exists()


@pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a GPU")
def test_ppo_trains_on_cuda(tmp_path):
    from socialnav.train.ppo.algorithm import train_ppo

    s = dataclasses.replace(load_ppo_settings("ppo_smoke"), device="cuda")
    result = train_ppo("wang2022", tmp_path / "run", s, progress=False, log=lambda _: None)
    assert result.finished and result.updates == 4


@pytest.mark.parametrize("argv, message", [
    (["--policy", "nosuch", "--config", "ppo_smoke"],
     "--policy 'nosuch': not a policy that `socialnav train` trains; value-based: cadrl, "),
    (["--policy", "orca"], "--policy 'orca': not a policy that `socialnav train` trains"),
    (["--policy", "sarl", "--config", "ppo_smoke"],
     "--config ppo_smoke: a PPO config, and sarl trains with the value-based trainer (its shipped configs: "
     "smoke)"),
    (["--policy", "crowdnav_pp", "--config", "smoke"],
     "--config smoke: a value-based config, and crowdnav_pp trains with the PPO trainer"),
    (["--policy", "crowdnav_pp", "--config", "ppo_smoke", "--env-steps", "0"],
     "--env-steps must be >= 1, got 0"),
    (["--policy", "crowdnav_pp", "--config", "ppo_smoke", "--collection-batch", "-3"],
     "--collection-batch must be >= 1, got -3"),
    (["--policy", "sarl", "--config", "smoke", "--rl-episodes", "-1"], "--rl-episodes must be >= 0, got -1"),
])
def test_command_line_mistakes_are_named_by_their_option(argv, message, tmp_path, capsys):
    from socialnav.cli import main

    out = tmp_path / "never"
    assert main(["train", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and ".yaml" not in err  # the option, not a config file the user never wrote
    assert not out.exists()


def test_config_file_mistakes_name_the_file(tmp_path, capsys):
    from socialnav.cli import main

    out = tmp_path / "never"
    rgl = tmp_path / "rgl.yaml"
    rgl.write_text("policy: rgl\nrl: {episodes: 4}\n")
    assert main(["train", "--policy", "sarl", "--config", str(rgl), "--out", str(out)]) == 2
    assert f"--config {rgl} sets policy: rgl, and --policy sarl" in capsys.readouterr().err
    same = tmp_path / "same.yaml"
    same.write_text("policy: ga3c_cadrl\nrl: {episodes: -1}\n")  # lstm_rl's alias: refused for -1 only
    assert main(["train", "--policy", "lstm_rl", "--config", str(same), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "sets policy" not in err and "episodes" in err
    if not torch.cuda.is_available():
        cuda = tmp_path / "cuda.yaml"
        cuda.write_text("device: cuda\n")
        assert main(["train", "--policy", "sarl", "--config", str(cuda), "--out", str(out)]) == 2
        assert f"--config {cuda}: device: cuda, and torch.cuda.is_available() is False" in (
            capsys.readouterr().err)
    assert main(["train", "--policy", "sarl", "--out", ""]) == 2
    assert "--out is empty (an unset shell variable?)" in capsys.readouterr().err
    assert not out.exists()


def test_a_budget_of_no_update_is_refused_in_a_config(tmp_path, capsys):
    from socialnav.cli import main

    config = tmp_path / "zero.yaml"
    config.write_text("total_env_steps: 0\n")
    argv = ["train", "--policy", "crowdnav_pp", "--config", str(config), "--out", str(tmp_path / "r")]
    assert main(argv) == 2
    assert "total_env_steps must be > 0, got 0" in capsys.readouterr().err


def test_a_users_config_of_the_other_trainer_is_named_as_such(tmp_path, capsys):
    from socialnav.cli import main

    ppo = tmp_path / "mine.yaml"
    ppo.write_text("n_envs: 4\nrollout_steps: 8\n")  # PPO settings only
    assert main(["train", "--policy", "sarl", "--config", str(ppo), "--out", str(tmp_path / "r")]) == 2
    assert (f"--config {ppo}: a PPO config, and sarl trains with the value-based trainer (its shipped "
            "configs: smoke)") in capsys.readouterr().err
    both = tmp_path / "threads.yaml"
    both.write_text("threads: 1\n")  # a setting of both trainers: not refused for either
    assert main(["train", "--policy", "sarl", "--config", str(both), "--rl-episodes", "-1",
                 "--out", str(tmp_path / "r")]) == 2
    assert "--rl-episodes must be >= 0" in capsys.readouterr().err


def test_a_curves_window_without_finished_episodes_has_no_rates():
    from socialnav.train.curves import window_columns

    rates = {"success": 0.0, "collision": 0.0, "timeout": 0.0}  # what an empty window's counters give
    assert window_columns(rates, 0) == {"train_episodes": 0}  # blank cells in curves.csv, not 0 % success
    assert window_columns({"success": 0.5, "collision": 0.25, "timeout": 0.25}, 4) == {
        "train_episodes": 4, "train_success": 0.5, "train_collision": 0.25, "train_timeout": 0.25}
