"""Adapters for outside RL libraries.

Stable-Baselines3's VecEnv over the native vector env (:mod:`socialnav.integrations.sb3`) and ``sb3:PATH``
policies for the evaluator (:mod:`socialnav.integrations.sb3_policy`). Each needs its library (``pip install
'socialnav[sb3]'``); importing this package needs none.
"""
