"""Replay memory: ring buffer semantics and reproducible sampling."""

import numpy as np
import pytest
import torch

from socialnav.train.value.memory import ReplayMemory


def _batch(k, n=2, start=0):
    ids = np.arange(start, start + k, dtype=np.float64)
    robot = np.repeat(ids[:, None], 9, axis=1)
    humans = np.repeat(ids[:, None, None], n * 5, axis=1).reshape(k, n, 5)
    mask = np.ones((k, n), dtype=bool)
    mask[:, -1] = ids % 2 == 0
    return robot, humans, mask, ids * 0.1, robot + 0.5, humans + 0.5, mask, ids % 3 == 0


def test_push_and_wraparound_keeps_newest():
    mem = ReplayMemory(5, n_humans=2)
    mem.push(*_batch(3))
    assert len(mem) == 3 and mem.position == 3
    mem.push(*_batch(4, start=3))  # ids 3..6; 5 and 6 overwrite slots 0 and 1
    assert len(mem) == 5 and mem.position == 2 and mem.pushed == 7
    assert sorted(mem.robot[:, 0].tolist()) == [2, 3, 4, 5, 6]
    assert mem.robot[0, 0] == 5 and mem.robot[1, 0] == 6
    # every field of a slot belongs to the same transition
    for i in range(5):
        tid = mem.robot[i, 0].item()
        assert mem.humans[i, 0, 0].item() == tid
        assert mem.next_robot[i, 0].item() == tid + 0.5
        assert mem.reward[i].item() == pytest.approx(tid * 0.1)
        assert mem.done[i].item() == (tid % 3 == 0)
        assert mem.mask[i, 1].item() == (tid % 2 == 0)


def test_push_more_than_capacity():
    mem = ReplayMemory(4, n_humans=2)
    mem.push(*_batch(2))
    mem.push(*_batch(10, start=2))  # only ids 8..11 survive
    assert len(mem) == 4
    assert sorted(mem.robot[:, 0].tolist()) == [8, 9, 10, 11]
    mem.push(*_batch(1, start=12))  # overwrites the oldest (8)
    assert sorted(mem.robot[:, 0].tolist()) == [9, 10, 11, 12]


def test_sampling_is_reproducible_and_within_size():
    mem = ReplayMemory(100, n_humans=2)
    mem.push(*_batch(7))
    a = mem.sample(50, torch.Generator().manual_seed(3))
    b = mem.sample(50, torch.Generator().manual_seed(3))
    assert torch.equal(a.robot, b.robot) and torch.equal(a.done, b.done)
    assert set(a.robot[:, 0].tolist()) <= set(range(7))
    assert a.humans.shape == (50, 2, 5) and a.mask.dtype == torch.bool
    # consistent rows: next state, reward and done belong to the sampled state
    assert torch.allclose(a.next_robot, a.robot + 0.5)
    assert torch.allclose(a.reward, a.robot[:, 0] * 0.1)


def test_errors():
    mem = ReplayMemory(3, n_humans=2)
    with pytest.raises(ValueError, match="empty"):
        mem.sample(1, torch.Generator())
    with pytest.raises(ValueError, match="humans must have shape"):
        mem.push(*_batch(2, n=3))
    with pytest.raises(ValueError):
        ReplayMemory(0, n_humans=1)
