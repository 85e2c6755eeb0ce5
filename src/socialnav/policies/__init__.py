"""Robot navigation policies: a registry of native (linear, ORCA, social force) and learned ones."""

from socialnav.policies.base import Policy, get_policy_entry, list_policies, make_policy, register_policy

__all__ = ["Policy", "get_policy_entry", "list_policies", "make_policy", "register_policy"]
