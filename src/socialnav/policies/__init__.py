"""Robot navigation policies: a registry of native (linear, ORCA, social force) and learned ones.

Example::

    from socialnav.policies import build_policy, make_policy
    from socialnav.presets import load_preset

    orca = make_policy("orca")
    sarl = build_policy("sarl", load_preset("wang2022"))  # the shipped checkpoint (needs PyTorch)

Learned policies are described by one record each (:class:`LearnedPolicySpec`, in
``socialnav/policies/learned_catalog.py``); :func:`register_learned_policy` adds one. Importing this
package never imports PyTorch; ``build_policy`` loads its module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from socialnav._runtime import lazy_exports
from socialnav.policies.learned_catalog import (
    LearnedPolicySpec,
    get_learned_spec,
    learned_policy_names,
    learned_policy_specs,
    register_learned_policy,
)
from socialnav.policies.registry import (
    RECORDED_ONLY,
    Policy,
    PolicyError,
    get_policy_entry,
    list_policies,
    make_policy,
    register_policy,
)

#: Public names whose module loads on first use (see ``lazy_exports``).
_EXPORTS = {
    "build_policy": "socialnav.policies.building",
    "shipped_checkpoint": "socialnav.policies.building",
    "list_shipped_checkpoints": "socialnav.policies.building",
}
__all__ = [
    "RECORDED_ONLY",
    "Policy",
    "PolicyError",
    "get_policy_entry",
    "list_policies",
    "make_policy",
    "register_policy",
    "LearnedPolicySpec",
    "get_learned_spec",
    "learned_policy_names",
    "learned_policy_specs",
    "register_learned_policy",
    "build_policy",
    "shipped_checkpoint",
    "list_shipped_checkpoints",
]

__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

if TYPE_CHECKING:  # what type checkers and IDEs see; at run time the names load lazily
    from socialnav.policies.building import build_policy, list_shipped_checkpoints, shipped_checkpoint
