"""A PPO policy's network arguments come from its learned-policy record (``network_kwargs``), the one
registration per policy: the shipped records give the arguments the trainer always used, a PPO
record without them is refused, and a registered record's arguments reach the trained network."""

import dataclasses

import pytest

import socialnav.policies.learned_catalog as catalog
from socialnav.train.ppo.settings import NetworkSettings, PPOSettings

SMALL = NetworkSettings(
    prediction_steps=3, robot_embed=16, human_hidden=8, attn_size=16, attn_heads=2, human_out=16,
    rh_attention=8, gru_input=8, gru_hidden=16, node_out=16, head_hidden=16, log_std_init=-0.5,
)


def test_crowdnav_pp_gets_every_network_size_and_the_normalisation_flag():
    s = PPOSettings(network=SMALL, normalize_obs=False)
    kwargs = catalog.get_learned_spec("crowdnav_pp").network_kwargs(s, 7)
    assert kwargs == {
        "normalize_obs": False, "prediction_steps": 3, "robot_embed": 16, "human_hidden": 8,
        "attn_size": 16, "attn_heads": 2, "human_out": 16, "rh_attention": 8, "gru_input": 8,
        "gru_hidden": 16, "node_out": 16, "head_hidden": 16, "self_attention": True, "log_std_init": -0.5,
    }


def test_ppo_mlp_gets_the_shared_prediction_and_sigma_its_width_and_the_human_slots():
    s = PPOSettings(policy="ppo_mlp", network=SMALL, mlp_hidden=24)
    kwargs = catalog.get_learned_spec("ppo_mlp").network_kwargs(s, 7)
    assert kwargs == {
        "prediction_steps": 3, "max_humans": 7, "hidden": 24, "normalize_obs": True, "log_std_init": -0.5,
    }


def test_a_ppo_record_without_network_kwargs_and_a_value_record_with_them_are_refused():
    ppo_mlp = catalog.get_learned_spec("ppo_mlp")
    with pytest.raises(ValueError, match="learned policy 'ppo_mlp': network_kwargs is required for PPO"):
        dataclasses.replace(ppo_mlp, network_kwargs=None)
    sarl = catalog.get_learned_spec("sarl")
    with pytest.raises(ValueError, match=r"learned policy 'sarl': network_kwargs .*\(trainer 'value'\)"):
        dataclasses.replace(sarl, network_kwargs=catalog.mlp_actor_critic_kwargs)




def test_a_registered_ppo_record_builds_the_network_it_declares(tmp_path, isolated_registries):
    from socialnav.policies.learned import load_checkpoint
    from socialnav.train.ppo.algorithm import train_ppo

    def narrow_mlp(settings, n_humans):  # a record's own arguments: a 6-wide MLP over 2 humans
        return {**catalog.mlp_actor_critic_kwargs(settings, n_humans), "hidden": 6, "max_humans": 2}

    spec = dataclasses.replace(
        catalog.get_learned_spec("ppo_mlp"), name="narrow_mlp", label="Narrow MLP", network_kwargs=narrow_mlp
    )
    catalog.register_learned_policy(spec)
    s = PPOSettings(
        policy="narrow_mlp", n_envs=4, rollout_steps=4, total_env_steps=16, epochs=1, minibatches=1,
        validate_every=1, val_episodes=2, threads=1,
    )
    result = train_ppo("wang2022", tmp_path / "run", s, progress=False, log=lambda _: None)
    ck = load_checkpoint(result.last_checkpoint, "narrow_mlp", -1)
    assert ck.model.model_kwargs()["hidden"] == 6 and ck.model.model_kwargs()["max_humans"] == 2
