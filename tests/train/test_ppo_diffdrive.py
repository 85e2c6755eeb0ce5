"""crowdnav_pp on a differential drive: it reads the robot's twist, trains and resumes mid-episode as an
uninterrupted run, and its checkpoint is refused under other limits (docs/kinematics.md)."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from socialnav.cli import main  # noqa: E402
from socialnav.policies.learned import load_checkpoint  # noqa: E402
from socialnav.policies.learned.attn_graph import AttnGraphNet  # noqa: E402
from socialnav.policies.learned.ppo_inputs import network_inputs, robot_width  # noqa: E402
from socialnav.presets import load_preset  # noqa: E402
from socialnav.scenarios import make_scenario  # noqa: E402
from socialnav.settings import ConfigError  # noqa: E402
from socialnav.sim import World, WorldSettings  # noqa: E402
from socialnav.train.ppo.algorithm import train_ppo  # noqa: E402
from tests.train.bit_identical_runs import run_digests  # noqa: E402
from tests.train.ppo_smoke import ppo_smoke  # noqa: E402


def _observation(kinematics: str, steps: int = 2):
    settings = WorldSettings(kinematics=kinematics, threads=1)
    with World(settings, make_scenario("circle_crossing", n_humans=3), 3, count=3) as world:
        obs = world.reset()
        for _ in range(steps):
            obs = world.step(np.tile([[1.0, 0.2]], (3, 1)), observe=True).observation
        return obs


def test_the_network_reads_the_features_then_the_twist():
    net = AttnGraphNet(robot_embed=8, human_hidden=8, attn_size=8, attn_heads=2, human_out=8, rh_attention=8,
                       gru_input=8, gru_hidden=8, node_out=8, head_hidden=8, twist_features=True)
    assert robot_width(net) == 11 and net.model_kwargs()["twist_features"] is True
    assert "twist_features" not in AttnGraphNet().model_kwargs()  # holonomic records unchanged
    obs = _observation("diff_drive")
    robot, _, _ = network_inputs(net, obs, 0.25, "cpu")
    assert robot.shape == (3, 11)
    np.testing.assert_allclose(robot[:, 9:].numpy(), obs.robot_twist, rtol=1e-6)
    with pytest.raises(ValueError, match="unicycle robot"):
        network_inputs(net, _observation("unicycle"), 0.25, "cpu")


def test_a_network_without_twist_inputs_is_refused_for_a_diff_drive(tmp_path):
    with pytest.raises(ConfigError, match="ppo_mlp.*cannot read a differential drive"):
        train_ppo(load_preset("wang2022_diffdrive"), tmp_path / "run", ppo_smoke(policy="ppo_mlp"),
                  progress=False, log=lambda _: None)


def test_trained_resumed_and_evaluated_on_the_diff_drive(tmp_path, capsys):
    preset = load_preset("wang2022_diffdrive")
    s = ppo_smoke()
    train_ppo(preset, tmp_path / "whole", s, progress=False, log=lambda _: None)
    # stopped mid-episode (8-step rollouts): the resumed robots go on from the twist they had
    train_ppo(preset, tmp_path / "split", s, progress=False, stop_after=2, log=lambda _: None)
    train_ppo(preset, tmp_path / "split", s, progress=False, log=lambda _: None)
    assert run_digests(tmp_path / "split") == run_digests(tmp_path / "whole")
    ck = load_checkpoint(tmp_path / "whole" / "best.pt", "crowdnav_pp", expected_input_dim=-1)
    assert ck.model.model_kwargs()["twist_features"] is True
    assert ck.model.model_kwargs()["log_std_init"] == -1.0  # nonholonomic_log_std_init: σ e⁻¹ at the start
    assert ck.config["preset"]["world"]["diff_drive"]["max_linear_acceleration"] == 2.5
    ev = tmp_path / "eval"
    rc = main(["evaluate", "--policy", "crowdnav_pp", "--checkpoint", str(tmp_path / "whole" / "best.pt"),
               "--preset", "wang2022_diffdrive", "--scenario", "circle_crossing", "--episodes", "3",
               "--visibility", "invisible", "--out", str(ev), "--no-progress"])
    assert rc == 0, capsys.readouterr().err
    assert json.loads((ev / "manifest.json").read_text())["preset"]["world"]["kinematics"] == "diff_drive"
    # under other acceleration limits the checkpoint is refused, naming the limit
    other = tmp_path / "other.yaml"
    other.write_text(resources.files("socialnav.configs").joinpath("wang2022_diffdrive.yaml").read_text()
                     .replace("name: wang2022_diffdrive", "name: slow_diffdrive")
                     .replace("max_linear_acceleration: 2.5", "max_linear_acceleration: 1.0"))
    rc = main(["evaluate", "--policy", "crowdnav_pp", "--checkpoint", str(tmp_path / "whole" / "best.pt"),
               "--preset", str(other), "--scenario", "circle_crossing", "--episodes", "2",
               "--visibility", "invisible", "--out", str(tmp_path / "eval2"), "--no-progress"])
    err = capsys.readouterr().err
    assert rc != 0 and "diff_drive.max_linear_acceleration 2.5 in the checkpoint" in err


@pytest.mark.parametrize("preset", ["wang2022_unicycle", "wang2022_diffdrive"])
def test_turn_penalty_takes_the_commanded_turn_squared_from_each_reward(tmp_path, preset):
    """CrowdNav++'s rotational penalty: the same first rollout (rewards do not steer it) with
    ``turn_penalty`` 0.05 has every reward lower by 0.05·dθ², dθ the heading change the world was sent."""
    import contextlib

    from socialnav.policies.learned.attn_graph import squash_actions
    from socialnav.train.ppo.algorithm import collect_rollout
    from socialnav.train.ppo.run import setup_ppo_run
    from socialnav.train.ppo.state import initial_state

    rollouts = []
    for penalty in (0.0, 0.05):
        s = ppo_smoke(turn_penalty=penalty, bootstrap_timeouts=False)
        with contextlib.ExitStack() as stack:
            run = setup_ppo_run(preset, tmp_path / f"run{penalty}", s, stack, progress=False,
                                log=lambda _: None)
            rollouts.append((collect_rollout(run, initial_state(run)), run))
            assert run.config["train"]["turn_penalty"] == penalty  # recorded at any value
    (plain, run), (penalised, _) = rollouts
    torch.testing.assert_close(plain.raws, penalised.raws, rtol=0, atol=0)
    w = run.preset.world
    # the heading change does not depend on v_pref
    turns = np.stack([
        squash_actions(raw.double().numpy(), w.kinematics, np.ones(len(raw)), w.rotation_limit)[:, 1]
        for raw in plain.raws
    ])
    assert (np.abs(turns) > 0.05).mean() > 0.5  # the penalty has turns to act on
    lower = (plain.rewards - penalised.rewards).numpy()
    np.testing.assert_allclose(lower, 0.05 * turns**2, rtol=1e-5, atol=1e-7)


def test_a_holonomic_run_neither_records_nor_uses_the_turn_penalty(tmp_path):
    import contextlib

    from socialnav.train.ppo.run import setup_ppo_run

    with contextlib.ExitStack() as stack:
        run = setup_ppo_run("wang2022", tmp_path / "run", ppo_smoke(), stack, progress=False,
                            log=lambda _: None)
        assert "turn_penalty" not in run.config["train"] and run.settings.turn_penalty == 0.05625
