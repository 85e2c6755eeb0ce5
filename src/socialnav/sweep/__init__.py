"""Sweeps: grids of evaluation and training jobs on this machine or a Ray cluster (docs/sweeps.md)."""
