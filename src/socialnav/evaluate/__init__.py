"""The evaluation protocol: plan, run, aggregate and report (see docs/protocol.md)."""
