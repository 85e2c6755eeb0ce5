"""The shipped checkpoints of the learned policies (``index.yaml`` lists them; docs/policies_learned.md)."""
