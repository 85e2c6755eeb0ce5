"""Tests of socialnav.policies.learned (need PyTorch)."""
