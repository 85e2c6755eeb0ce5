"""The registration records of the learned policies are the one source of their facts: a policy
registered in a test appears in ``socialnav list``, the train CLI, the training defaults, checkpoint
saving/loading and result labels, and the docs table is the records' table."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from socialnav.policies import learned_catalog as catalog
from socialnav.policies.learned_catalog import LearnedPolicySpec, register_learned_policy

DOCS = Path(__file__).resolve().parents[2] / "docs" / "policies_learned.md"


def tiny_sarl(**kwargs):
    """A SARL network small enough for a test (the dummy policy's network)."""
    from socialnav.policies.learned.sarl import SARL

    widths = dict(mlp1_dims=(8, 6), mlp2_dims=(6, 4), attention_dims=(6, 1), mlp3_dims=(8, 1))
    return SARL(**{**widths, **kwargs})


def dummy_spec(**changes) -> LearnedPolicySpec:
    fields = dict(
        name="dummy_attention",
        network=tiny_sarl,
        description="a test's policy: a tiny SARL",
        label="Dummy (test)",
        trainer="value",
        observes="robot state + joint states",
        paper="none",
        paper_row="DUMMY",
        aliases={"dummy_alias": "alias of dummy_attention"},
        defaults={"planning_depth": 3, "reward_rule": "swept"},
        one_human_training=True,
    )
    return LearnedPolicySpec(**{**fields, **changes})


def test_the_shipped_records():
    assert catalog.learned_policy_names("value") == [
        "cadrl", "lstm_rl", "ga3c_cadrl", "sarl", "om_sarl", "rgl", "mp_rgl"
    ]
    assert catalog.learned_policy_names("ppo") == ["crowdnav_pp", "ppo_mlp", "lidar_ppo"]
    assert catalog.canonical_name("ga3c_cadrl") == "lstm_rl"
    mp = catalog.get_learned_spec("mp_rgl")
    assert mp.value_defaults == {
        "information": "learned", "planning_depth": 2, "planning_width": 2, "reward_rule": "swept"
    }
    assert mp.evaluation_parameters() == {
        "information": "learned", "device": "cpu", "planning_depth": 2, "planning_width": 2, "scorer": "auto"
    }
    assert catalog.get_learned_spec("sarl").value_defaults == dict(catalog.VALUE_DEFAULTS)
    assert catalog.get_learned_spec("crowdnav_pp").evaluation_parameters() == {
        "device": "cpu", "deterministic": True
    }
    assert [s.name for s in catalog.learned_policy_specs() if s.one_human_training] == ["cadrl"]


def test_the_docs_table_is_the_records_table():
    text = DOCS.read_text()
    start = text.index("<!-- learned-policies-table")
    block = text[text.index("\n", start) + 1 : text.index("\n<!-- end learned-policies-table -->")]
    assert block == catalog.markdown_table()


def test_every_shipped_record_names_an_importable_network():
    pytest.importorskip("torch")
    from torch import nn

    for name in catalog.learned_policy_names():
        assert issubclass(type(catalog.get_learned_spec(name).network_factory()()), nn.Module), name


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"trainer": "sac"}, "trainer 'sac' is not a built-in trainer (value, ppo): give checkpoint_kind"),
        ({"checkpoint_kind": "q_values"}, "checkpoint_kind 'q_values' must be one of"),
        ({"defaults": {"planning_dept": 2}}, "unknown default(s) ['planning_dept']"),
        ({"trainer": "ppo"}, "lookahead defaults apply to value-based policies only"),
        ({"required_information": "learned"}, "required_information 'learned' must also be its default"),
    ],
)
def test_a_malformed_record_is_refused_naming_the_field(changes, message):
    with pytest.raises(ValueError, match=r"learned policy 'dummy_attention'") as err:
        dummy_spec(**changes)
    assert message in str(err.value)


def test_a_taken_name_or_alias_is_refused(isolated_registries):
    with pytest.raises(ValueError, match="'sarl' is already registered"):
        register_learned_policy(dummy_spec(name="sarl"))
    with pytest.raises(ValueError, match="'ga3c_cadrl' is already registered"):
        register_learned_policy(dummy_spec(aliases={"ga3c_cadrl": "taken"}))


def test_a_registered_record_reaches_list_train_and_labels(isolated_registries, capsys):
    from socialnav.cli import main
    from socialnav.policies.learned_catalog import default_label, default_paper_row
    from socialnav.presets import load_preset
    from socialnav.train.value.settings import TrainSettings
    from socialnav.train.worlds import training_n_humans

    register_learned_policy(dummy_spec())
    assert main(["list", "--json"]) == 0
    listed = {p["name"]: p for p in json.loads(capsys.readouterr().out)["policies"]}
    for name, description in (("dummy_attention", "a test's policy: a tiny SARL"),
                              ("dummy_alias", "alias of dummy_attention")):
        assert listed[name]["learned"] is True
        assert listed[name]["description"] == description
        assert listed[name]["parameters"] == {
            "information": "constant_velocity", "device": "cpu", "planning_depth": 3, "planning_width": 1,
            "scorer": "auto",
        }
    resolved = TrainSettings().resolved("dummy_attention")
    assert (resolved.information, resolved.planning_depth, resolved.planning_width, resolved.reward_rule) == (
        "constant_velocity", 3, 1, "swept"
    )
    preset = load_preset("wang2022")
    assert training_n_humans(preset, "dummy_attention") == 1
    assert training_n_humans(preset, "dummy_attention", cadrl_one_human=False) == preset.training.n_humans
    assert (default_label("dummy_alias"), default_paper_row("dummy_attention")) == ("Dummy (test)", "DUMMY")
    with pytest.raises(SystemExit):
        main(["train", "--help"])
    assert "dummy_attention, dummy_alias" in " ".join(capsys.readouterr().out.split())


def test_a_record_requiring_one_information_refuses_another(isolated_registries):
    from socialnav.settings import ConfigError
    from socialnav.train.value.settings import TrainSettings

    register_learned_policy(dummy_spec(required_information="oracle", defaults={"information": "oracle"}))
    assert TrainSettings().resolved("dummy_attention").information == "oracle"
    expected = "dummy_attention trains with it only, so it needs 'oracle', got 'learned'"
    with pytest.raises(ConfigError, match=expected):
        TrainSettings(information="learned").resolved("dummy_attention")


def test_a_registered_record_saves_loads_and_acts(isolated_registries, tmp_path):
    pytest.importorskip("torch")
    import torch

    from socialnav.policies.building import build_policy
    from socialnav.policies.learned import build, load_checkpoint, save_checkpoint
    from socialnav.policies.learned_loading import LearnedPolicy
    from socialnav.presets import load_preset
    from socialnav.scenarios import make_scenario
    from socialnav.sim.world import World

    register_learned_policy(dummy_spec())
    preset = load_preset("wang2022")
    torch.manual_seed(0)
    net = build("dummy_alias")  # an alias builds the policy's network
    world = preset.world
    value_policy = {
        "kinematics": world.kinematics, "gamma": 0.9, "information": "constant_velocity",
        "planning_depth": 1, "planning_width": 1, "reward_rule": "end",
        "rotation_limit": world.rotation_limit, "dt": world.dt,
        "reward": {k: getattr(world.reward, k) for k in (
            "success_reward", "collision_penalty", "discomfort_dist", "discomfort_penalty_factor"
        )} | {"time_step": world.dt},
    }
    path = save_checkpoint(tmp_path / "dummy.pt", "dummy_alias", net, config={"value_policy": value_policy})
    assert load_checkpoint(path, "dummy_attention").policy == "dummy_attention"  # the name stored
    policy = build_policy("dummy_attention", preset, path)
    assert isinstance(policy, LearnedPolicy) and policy.name == "dummy_attention"
    observation = World(preset.world, make_scenario("circle_crossing", n_humans=3), 2).reset()
    actions = policy.act(observation)
    assert actions.shape == (2, 2) and np.isfinite(actions).all()
    speed = np.hypot(actions[:, 0], actions[:, 1])
    assert np.all(speed <= observation.robot[:, 7] + 1e-9) and np.any(speed > 0)


def test_an_alias_finds_its_policys_shipped_checkpoint():
    # `--policy ga3c_cadrl` without --checkpoint: lstm_rl's shipped network, which it names
    from socialnav.policies.building import build_policy, shipped_checkpoint
    from socialnav.presets import load_preset

    lstm = shipped_checkpoint("lstm_rl", "wang2022")
    assert lstm is not None and shipped_checkpoint("ga3c_cadrl", "wang2022") == lstm
    policy = build_policy("ga3c_cadrl", load_preset("wang2022"), None)
    assert policy.describe()["policy"] == "ga3c_cadrl"
    assert policy.describe()["checkpoint"] == str(lstm)
