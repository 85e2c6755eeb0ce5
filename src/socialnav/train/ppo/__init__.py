"""The PPO trainer (``ppo``): a recurrent actor-critic, every environment stepped in lockstep.

``algorithm.py`` is the trainer, CleanRL-style in one module: the update loop, the rollout, GAE, the
clipped objective and the minibatch epochs, read top to bottom. Around it: setup (``run.py``), the
typed state and ``last.pt`` (``state.py``), the lockstep step and world snapshots (``worlds.py``),
validation and curves rows (``validation.py``), settings (``settings.py``). docs/ppo.md explains it.
"""
