"""Test policies for sweeps: straight to the goal, and the same policy whose worker process dies the
first time it acts (a process killed mid-chunk, as by the OOM killer or a lost machine)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


class StraightToGoal:
    """Straight to the goal at v_pref (picklable, so a sweep sends it to its workers)."""

    information = "none"

    def __init__(self, marker: str = "") -> None:
        self.name = "straight"
        self.marker = marker

    def act(self, observation):
        to_goal = observation.robot[:, 5:7] - observation.robot[:, 0:2]
        dist = np.maximum(np.linalg.norm(to_goal, axis=1, keepdims=True), 1e-9)
        return to_goal / dist * np.minimum(observation.robot[:, 7:8], dist / observation.dt)

    def describe(self):
        return {"policy": self.name, "information": self.information}


class DiesOnce(StraightToGoal):
    """Kills its own process the first time any worker acts (``marker`` records that it happened;
    where it cannot be written, every time)."""

    def act(self, observation):
        marker = Path(self.marker)
        if not marker.exists():
            try:
                marker.write_text(str(os.getpid()))
            except OSError:
                pass  # a marker that cannot be written: the worker dies every time
            os._exit(137)
        return super().act(observation)


def value_or_death(_payload, i: int, deadly: tuple[int, ...]) -> int:
    """An executor task: returns ``i``, or kills its worker process when ``i`` is in ``deadly``."""
    if i in deadly:
        os._exit(137)
    return i


def ignore_sigterm_and_sleep(ready) -> None:
    """A process that SIGTERM does not stop (``ready`` is set once it ignores it); only SIGKILL ends it."""
    import signal
    import time

    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    ready.set()
    time.sleep(600)
