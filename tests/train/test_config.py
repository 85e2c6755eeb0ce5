"""Training settings: YAML with strict keys, derived seeds."""

import json

import pytest

from socialnav.settings import ConfigError
from socialnav.train.run_directory import derive_seeds
from socialnav.train.value.settings import TrainSettings, load_train_settings


def test_defaults_follow_the_spec():
    s = TrainSettings()
    assert (s.imitation.episodes, s.imitation.epochs, s.imitation.lr, s.imitation.batch_size) == (
        2000,
        50,
        1e-3,
        100,
    )
    assert s.imitation.teacher_safety_space == 0.15
    rl = s.rl
    assert (rl.episodes, rl.epsilon_start, rl.epsilon_end, rl.epsilon_decay_episodes) == (
        10000,
        0.5,
        0.1,
        4000,
    )
    assert (
        rl.capacity,
        rl.batch_size,
        rl.lr,
        rl.target_update_every,
        rl.validate_every,
        rl.val_episodes,
        rl.gamma,
    ) == (100000, 100, 1e-3, 1000, 1000, 100, 0.9)
    # The lookahead defaults depend on the policy: constant velocity, one step, end-of-step reward for
    # the CrowdNav family and RGL; MP-RGL plans 2 deep and 2 wide with its learned predictor.
    assert s.information == ""
    for policy in ("cadrl", "lstm_rl", "sarl", "om_sarl", "rgl"):
        r = s.resolved(policy)
        assert (r.information, r.planning_depth, r.planning_width, r.reward_rule) == (
            "constant_velocity",
            1,
            1,
            "end",
        )
    r = s.resolved("mp_rgl")
    assert (r.information, r.planning_depth, r.planning_width, r.reward_rule) == ("learned", 2, 2, "swept")


def test_mp_rgl_refuses_to_train_without_its_predictor_and_oracle_refuses_planning():
    import dataclasses

    import pytest

    from socialnav.settings import ConfigError

    s = load_train_settings()
    with pytest.raises(ConfigError, match="mp_rgl plans with the state predictor"):
        dataclasses.replace(s, information="constant_velocity").resolved("mp_rgl")
    with pytest.raises(ConfigError, match="oracle gives one"):
        dataclasses.replace(s, information="oracle", planning_depth=2).resolved("sarl")


def test_resume_accepts_runs_saved_before_the_planning_settings_existed():
    from socialnav.train.value.settings import resume_diff

    current = {
        "train": {
            "seed": 0,
            "planning_depth": 1,
            "planning_width": 1,
            "reward_rule": "end",
            "predictor_lr": 1e-3,
        },
        "value_policy": {"gamma": 0.9, "planning_depth": 1, "planning_width": 1, "reward_rule": "end"},
    }
    old = {"train": {"seed": 0}, "value_policy": {"gamma": 0.9}}
    assert resume_diff(old, current) == []
    # ...but not when the new setting takes another value than such runs had.
    deeper = {**current, "value_policy": {**current["value_policy"], "planning_depth": 2}}
    assert resume_diff(old, deeper) == ["value_policy.planning_depth"]
    assert resume_diff({**old, "train": {"seed": 1}}, current) == ["train.seed"]


def test_yaml_loads_nested_and_overrides(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text(
        "seed: 3\ncollection_batch: 32\nrl:\n  episodes: 50\n  gradient_steps_per_episode: 2\n"
        "imitation: {epochs: 1}\n"
    )
    s = load_train_settings(p, seed=7, device=None)
    assert s.seed == 7 and s.collection_batch == 32 and s.device == "cpu"
    assert s.rl.episodes == 50 and s.rl.gradient_steps_per_episode == 2.0 and s.imitation.epochs == 1
    assert s.rl.batch_size == 100  # untouched defaults survive


@pytest.mark.parametrize(
    "text, match",
    [
        ("colection_batch: 3\n", "unknown setting.*colection_batch.*valid"),
        ("rl: {episdes: 3}\n", "rl.episdes"),
        ("rl: {episodes: many}\n", "rl.episodes"),
        ("information: psychic\n", "information"),
        ("imitation: {lr: -1}\n", "imitation.lr"),
        ("- a\n- b\n", "mapping"),
        ("rl: {capacity: 50, batch_size: 100}\n", r"rl.batch_size must be <= rl.capacity \(50\)"),
        ("rl: {capacity: 500, warmup_transitions: 1000}\n",
         r"rl.warmup_transitions must be <= rl.capacity \(500\).*no gradient step"),
    ],
)
def test_yaml_strict_keys_and_values(tmp_path, text, match):
    p = tmp_path / "bad.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_train_settings(p)


def test_missing_file():
    with pytest.raises(ConfigError, match="does not exist"):
        load_train_settings("/nonexistent/x.yaml")


def test_seeds_are_separate_and_derived():
    a, b = derive_seeds(0), derive_seeds(1)
    assert a == derive_seeds(0)
    assert len({a["exploration"], a["init"], a["sampling"]}) == 3
    assert a["exploration"] != b["exploration"] and a["init"] != b["init"]
    assert a["scenario_start"] != b["scenario_start"]


def test_a_seed_from_the_command_line_is_bounded_and_named_as_the_options():
    from socialnav.settings import ConfigError

    with pytest.raises(ConfigError, match=r"^--seed: seed must be in \[0, 4294967295\], got 1000000000000$"):
        load_train_settings("smoke", seed=10**12)
    assert load_train_settings("smoke", seed=2**32 - 1).seed == 2**32 - 1


def test_a_run_directory_of_another_policy_is_named_as_such(tmp_path):
    from socialnav.policies.learned import build, save_checkpoint
    from socialnav.settings import ConfigError
    from socialnav.train.run_directory import load_resume_checkpoint

    save_checkpoint(tmp_path / "last.pt", "sarl", build("sarl"), {}, {})
    with pytest.raises(ConfigError, match=rf"{tmp_path} holds a training run of another policy \("
                       rf"checkpoint {tmp_path}/last.pt holds policy 'sarl', expected 'cadrl'.*train 'cadrl' "
                       r"into another --out"):
        load_resume_checkpoint(tmp_path / "last.pt", "cadrl", tmp_path)


def test_a_runs_own_config_file_is_a_training_config(tmp_path):
    # a refused resume points to the run's config.yaml: --config takes it (its train section), for the
    # value-based and the PPO trainer, and the command line's trainer check reads its kind from it
    import yaml

    from socialnav.train.cli import _config_trainer, _read_config
    from socialnav.train.ppo.settings import PPOSettings, load_ppo_settings

    settings = load_train_settings("smoke", seed=7)
    record = {"value_policy": {"dt": 0.25}, "policy": "sarl", "preset": {"name": "wang2022"},
              "train": settings.to_dict(), "seeds": {}, "n_humans": 5}
    path = tmp_path / "config.yaml"
    path.write_text(yaml.safe_dump(record))
    assert load_train_settings(path) == settings
    assert _config_trainer(_read_config(str(path))) == "value"
    ppo = load_ppo_settings("ppo_smoke", seed=3)
    path.write_text(yaml.safe_dump({"ppo_policy": {}, "policy": "crowdnav_pp", "preset": {},
                                    "train": json.loads(json.dumps(ppo.to_dict()))}))
    assert load_ppo_settings(path) == ppo and isinstance(ppo, PPOSettings)
    assert _config_trainer(_read_config(str(path))) == "ppo"


def test_resuming_under_an_alias_of_the_runs_policy_is_no_difference():
    from socialnav.train.value.settings import resume_diff

    saved = {"policy": "ga3c_cadrl", "train": {"policy": "ga3c_cadrl", "seed": 0}}
    assert resume_diff(saved, {"policy": "lstm_rl", "train": {"policy": "lstm_rl", "seed": 0}}) == []
    assert resume_diff(saved, {"policy": "sarl", "train": {"policy": "sarl", "seed": 0}}) == [
        "policy", "train.policy"]
