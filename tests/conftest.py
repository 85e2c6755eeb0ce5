"""Fixtures shared by several test packages."""

import pytest

import socialnav.policies.learned_catalog as learned_catalog
import socialnav.policies.registry as policy_registry


@pytest.fixture()
def isolated_registries(monkeypatch):
    """Policy and learned-policy registrations made by a test are undone after it."""
    monkeypatch.setattr(learned_catalog, "_SPECS", dict(learned_catalog._SPECS))
    monkeypatch.setattr(learned_catalog, "_ALIASES", dict(learned_catalog._ALIASES))
    policy_registry._load_builtin()
    monkeypatch.setattr(policy_registry, "_REGISTRY", dict(policy_registry._REGISTRY))
