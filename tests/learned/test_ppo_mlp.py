"""ppo_mlp: nearest-humans input (hand-checked), padding and order invariance, and a PPO run that
trains it and is evaluated through the policy registry."""

import numpy as np
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from socialnav.policies.learned.ppo_mlp import MLPActorCritic


def test_input_keeps_the_nearest_humans_nearest_first():
    net = MLPActorCritic(prediction_steps=0, max_humans=2, hidden=8, normalize_obs=False)
    humans = torch.tensor([[[3.0, 0.0], [1.0, 0.0], [0.0, 2.0], [0.5, 0.0]]])
    mask = torch.tensor([[True, True, True, False]])  # the nearest slot is padding
    x = net.flat_input(torch.arange(9.0)[None], humans, mask)
    # robot (9), then (1, 0) flag 1, then (0, 2) flag 1; the human at 3 m is left out
    assert x[0].tolist() == [*range(9), 1.0, 0.0, 1.0, 0.0, 2.0, 1.0]
    few = net.flat_input(torch.zeros(1, 9), humans[:, :1], mask[:, :1])
    assert few[0, 9:].tolist() == [3.0, 0.0, 1.0, 0.0, 0.0, 0.0]  # one human, then an empty slot


@settings(max_examples=30, deadline=None)
@given(n_real=st.integers(0, 4), n_pad=st.integers(1, 3), seed=st.integers(0, 2**16))
def test_padded_humans_and_their_order_change_nothing(n_real, n_pad, seed):
    torch.manual_seed(seed % 5)
    net = MLPActorCritic(max_humans=3, hidden=16).eval()
    g = torch.Generator().manual_seed(seed)
    robot = torch.randn(2, 9, generator=g)
    humans = torch.randn(2, n_real, net.input_dim, generator=g)
    h = net.initial_state(2)
    start = torch.zeros(2, dtype=torch.bool)
    mean, value, _ = net.step(robot, humans, torch.ones(2, n_real, dtype=torch.bool), h, start)
    perm = torch.randperm(n_real + n_pad, generator=g)
    padded = torch.cat([humans, torch.randn(2, n_pad, net.input_dim, generator=g) * 100], 1)[:, perm]
    mask = torch.cat([torch.ones(2, n_real, dtype=torch.bool), torch.zeros(2, n_pad, dtype=torch.bool)], 1)[
        :, perm
    ]
    mean2, value2, _ = net.step(robot, padded, mask, h, start)
    torch.testing.assert_close(mean2, mean)
    torch.testing.assert_close(value2, value)


def test_sequence_equals_steps():
    net = MLPActorCritic(hidden=16).eval()
    g = torch.Generator().manual_seed(0)
    robot, humans = torch.randn(4, 3, 9, generator=g), torch.randn(4, 3, 5, net.input_dim, generator=g)
    mask = torch.rand(4, 3, 5, generator=g) > 0.3
    starts = torch.zeros(4, 3, dtype=torch.bool)
    mean, value = net.sequence(robot, humans, mask, net.initial_state(3), starts)
    for t in range(4):
        m, v, _ = net.step(robot[t], humans[t], mask[t], net.initial_state(3), starts[t])
        torch.testing.assert_close(mean[t], m)
        torch.testing.assert_close(value[t], v)


def test_ppo_trains_the_mlp_and_the_registry_loads_it(tmp_path):
    from socialnav.policies.building import build_policy
    from socialnav.presets import load_preset
    from socialnav.train.ppo.algorithm import train_ppo
    from socialnav.train.ppo.settings import PPOSettings

    s = PPOSettings(
        policy="ppo_mlp",
        n_envs=8,
        rollout_steps=4,
        total_env_steps=64,
        epochs=1,
        minibatches=2,
        validate_every=2,
        val_episodes=4,
        threads=1,
        mlp_hidden=16,
    )
    result = train_ppo("wang2022", tmp_path / "run", s, progress=False, log=lambda _: None)
    assert result.finished and result.updates == 2
    policy = build_policy("ppo_mlp", load_preset("wang2022"), result.best_checkpoint)
    assert policy.network.max_humans == 5 and policy.describe()["policy"] == "ppo_mlp"
    from socialnav.sim.observation import Observation

    obs = Observation(
        np.tile([0.0, -4.0, 0, 0, 0.3, 0.0, 4.0, 1.5, 1.57], (2, 1)),
        np.zeros((2, 1, 5)),
        np.zeros((2, 1), bool),
        np.ones(2, bool),
        np.zeros(2),
        0.25,
        "holonomic",
    )
    actions = policy.act(obs)
    assert actions.shape == (2, 2) and (np.hypot(*actions.T) <= 1.5 + 1e-12).all()
