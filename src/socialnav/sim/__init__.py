"""The batched simulator: world, settings, observations, and the single-step ORCA solver."""

from socialnav.sim.orca_solver import orca_step

__all__ = ["orca_step"]
