"""Fixtures shared by several test packages."""

import pytest

import socialnav.policies.base as policy_base
import socialnav.policies.learned_catalog as learned_catalog


@pytest.fixture()
def isolated_registries(monkeypatch):
    """Policy and learned-policy registrations made by a test are undone after it."""
    monkeypatch.setattr(learned_catalog, "_SPECS", dict(learned_catalog._SPECS))
    monkeypatch.setattr(learned_catalog, "_ALIASES", dict(learned_catalog._ALIASES))
    policy_base._load_builtin()
    monkeypatch.setattr(policy_base, "_REGISTRY", dict(policy_base._REGISTRY))
