"""The Gymnasium environments over the batched world, and the wrappers giving a learner's observation.

Two layers above the world (they take a protocol preset's defaults): the single env
(:class:`SocialNavEnv`, ``gym.make("socialnav/CircleCrossing-v0")``), the native vector env
(:class:`SocialNavVectorEnv`), the learner wrappers (:class:`LearnerObservation`,
:class:`LearnerObservationVector`), the Gymnasium ids (:data:`ENV_IDS`, registered by ``import socialnav``)
and the render hooks. Users import them from :mod:`socialnav.sim` (``from socialnav.sim import
SocialNavEnv``) or from here; docs/simulator.md describes them.

Importing this package imports no submodule; each name loads its module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports

#: Public name → the module that defines it (imported on first use: see ``lazy_exports``).
_EXPORTS = {
    "SocialNavEnv": "socialnav.envs.single",
    "SocialNavVectorEnv": "socialnav.envs.vector",
    "RAW_PARTS": "socialnav.envs.config",
    "ENV_IDS": "socialnav.envs.registration",
    "LearnerObservation": "socialnav.envs.learner_wrappers",
    "LearnerObservationVector": "socialnav.envs.learner_wrappers",
    "register_viewer": "socialnav.envs.render",
}
__all__ = [
    "SocialNavEnv",
    "SocialNavVectorEnv",
    "RAW_PARTS",
    "ENV_IDS",
    "LearnerObservation",
    "LearnerObservationVector",
    "register_viewer",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.envs.config import RAW_PARTS
    from socialnav.envs.learner_wrappers import LearnerObservation, LearnerObservationVector
    from socialnav.envs.registration import ENV_IDS
    from socialnav.envs.render import register_viewer
    from socialnav.envs.single import SocialNavEnv
    from socialnav.envs.vector import SocialNavVectorEnv
