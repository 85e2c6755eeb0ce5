"""The batched simulator: the world, its settings, observations and their named parts, actions.

It also gives the Gymnasium envs' public names (``SocialNavEnv``, ``SocialNavVectorEnv``, ``ENV_IDS``,
``LearnerObservation``, ...), which live two layers up, in :mod:`socialnav.envs`; they load only when used.

Example::

    from socialnav.scenarios import make_scenario
    from socialnav.sim import World, WorldSettings

    world = World(WorldSettings(), make_scenario("circle_crossing", n_humans=5), batch_size=64)
    observation = world.reset()

Importing this package imports no submodule; each name below loads its module on first use (the
simulator never imports PyTorch). See docs/simulator.md.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "World": "socialnav.sim.world",
    "StepResult": "socialnav.sim.world",
    "EpisodeStream": "socialnav.sim.world",
    "check_world_size": "socialnav.sim.world",
    "WorldSettings": "socialnav.sim.settings",
    "OrcaSettings": "socialnav.sim.settings",
    "SocialForceSettings": "socialnav.sim.settings",
    "RewardSettings": "socialnav.sim.settings",
    "SensingSettings": "socialnav.sim.settings",
    "DiffDriveSettings": "socialnav.sim.settings",
    "lidar_scan": "socialnav.sim.sensing",
    "lidar_beam_angles": "socialnav.sim.sensing",
    "disc_in_sight": "socialnav.sim.sensing",
    "HUMAN_MODELS": "socialnav.sim.settings",
    "HumanBehaviour": "socialnav.sim.behaviours",
    "HumanState": "socialnav.sim.behaviours",
    "register_human_behaviour": "socialnav.sim.behaviours",
    "list_human_behaviours": "socialnav.sim.behaviours",
    "Observation": "socialnav.sim.observation",
    "discrete_actions": "socialnav.sim.actions",
    "orca_step": "socialnav.sim.orca_solver",
    "ObservationSettings": "socialnav.sim.learner_obs",
    "ObservationTransform": "socialnav.sim.learner_obs",
    "ObservationPart": "socialnav.sim.parts.base",
    "register_observation_part": "socialnav.sim.parts.registry",
    "list_observation_parts": "socialnav.sim.parts.registry",
    # the Gymnasium envs (socialnav.envs, two layers up): their public path is this package's
    "SocialNavEnv": "socialnav.envs.single",
    "SocialNavVectorEnv": "socialnav.envs.vector",
    "ENV_IDS": "socialnav.envs.registration",
    "LearnerObservation": "socialnav.envs.learner_wrappers",
    "LearnerObservationVector": "socialnav.envs.learner_wrappers",
    "register_viewer": "socialnav.envs.render",
}
__all__ = [
    "World",
    "StepResult",
    "EpisodeStream",
    "check_world_size",
    "WorldSettings",
    "OrcaSettings",
    "SocialForceSettings",
    "RewardSettings",
    "SensingSettings",
    "DiffDriveSettings",
    "lidar_scan",
    "lidar_beam_angles",
    "disc_in_sight",
    "HUMAN_MODELS",
    "HumanBehaviour",
    "HumanState",
    "register_human_behaviour",
    "list_human_behaviours",
    "Observation",
    "discrete_actions",
    "orca_step",
    "SocialNavEnv",
    "SocialNavVectorEnv",
    "ENV_IDS",
    "ObservationSettings",
    "ObservationTransform",
    "ObservationPart",
    "register_observation_part",
    "list_observation_parts",
    "LearnerObservation",
    "LearnerObservationVector",
    "register_viewer",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.envs.learner_wrappers import LearnerObservation, LearnerObservationVector
    from socialnav.envs.registration import ENV_IDS
    from socialnav.envs.render import register_viewer
    from socialnav.envs.single import SocialNavEnv
    from socialnav.envs.vector import SocialNavVectorEnv
    from socialnav.sim.actions import discrete_actions
    from socialnav.sim.behaviours import (
        HumanBehaviour,
        HumanState,
        list_human_behaviours,
        register_human_behaviour,
    )
    from socialnav.sim.learner_obs import ObservationSettings, ObservationTransform
    from socialnav.sim.observation import Observation
    from socialnav.sim.orca_solver import orca_step
    from socialnav.sim.parts.base import ObservationPart
    from socialnav.sim.parts.registry import list_observation_parts, register_observation_part
    from socialnav.sim.settings import (
        HUMAN_MODELS,
        OrcaSettings,
        RewardSettings,
        SocialForceSettings,
        WorldSettings,
    )
    from socialnav.sim.world import EpisodeStream, StepResult, World, check_world_size
