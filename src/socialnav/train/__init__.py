"""Training of the learned policies: imitation from ORCA, then value-based RL (needs torch)."""
