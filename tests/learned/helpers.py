"""Shared scene builders for the learned-policy tests."""

from __future__ import annotations

import numpy as np

NETWORKS = ["cadrl", "lstm_rl", "sarl", "om_sarl", "rgl", "mp_rgl"]
#: A small attention-graph network (crowdnav_pp) for fast tests; the layer widths of AttnGraphNet.
SMALL_ATTN_GRAPH = dict(
    robot_embed=32,
    human_hidden=16,
    attn_size=32,
    attn_heads=4,
    human_out=32,
    rh_attention=16,
    gru_input=16,
    gru_hidden=32,
    node_out=32,
    head_hidden=32,
)


def random_scene(rng: np.random.Generator, b: int, n: int, p_real: float = 0.7, garbage: float = 0.0):
    """Random robots/humans; padded slots hold ``garbage``-scaled noise (or zeros)."""
    robot = np.zeros((b, 9))
    robot[:, 0:2] = rng.uniform(-3, 3, (b, 2))
    robot[:, 2:4] = rng.uniform(-1, 1, (b, 2))
    robot[:, 4] = 0.3
    robot[:, 5:7] = rng.uniform(-4, 4, (b, 2))
    robot[:, 7] = rng.uniform(0.5, 1.5, b)
    robot[:, 8] = rng.uniform(-np.pi, np.pi, b)
    humans = np.zeros((b, n, 5))
    humans[..., 0:2] = rng.uniform(-4, 4, (b, n, 2))
    humans[..., 2:4] = rng.uniform(-1, 1, (b, n, 2))
    humans[..., 4] = rng.uniform(0.3, 0.5, (b, n))
    mask = rng.random((b, n)) < p_real
    if garbage:
        noise = rng.normal(0, garbage, (b, n, 5))
        humans = np.where(mask[..., None], humans, noise)
    return robot, humans, mask


def obs_dict(robot, humans, mask, dt=0.25):
    return {"robot": robot, "humans": humans, "human_mask": mask, "dt": dt}
