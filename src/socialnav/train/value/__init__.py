"""The value-based trainer (``value``): imitation from ORCA, then value-based RL (CrowdNav/RGL).

``trainer.py`` reads top to bottom as the run's phases: setup (``run.py``), resume (``state.py``) or
imitation and the first validation (``imitation_phase.py``, ``imitation.py``), then the RL loop
(``rl_phase.py``; TD targets, losses and the RGL repository's storage rule: ``rl.py``; the replay
memory: ``memory.py``; the compiled gradient step: ``fused_step.py``). Settings: ``settings.py``.
docs/training.md explains it.
"""
