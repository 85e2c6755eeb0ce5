"""Planners in any language: ``exec:COMMAND`` runs a program and steps it over its stdin and stdout.

The program is started once (per evaluation process) and, every step, receives the batch of
observations and answers with the batch of actions, in the versioned exchange of docs/exec_protocol.md:

1. socialnav writes a hello line (JSON): ``{"protocol": "socialnav-exec", "version": 1, "kinematics",
   "dt", "robot_columns", "human_columns", "formats": ["json", "binary"]}``;
2. the planner answers with one JSON line: ``{"protocol": "socialnav-exec", "version": 1, "format":
   "json" | "binary", "name": ...}`` (``name`` optional, recorded with the results);
3. each step, socialnav writes one observation frame and the planner one action frame, in the format
   it chose: a JSON line each (the friendly default), or binary frames of little-endian arrays (for
   speed; the C++ example planner uses them).

A planner that exits, hangs past ``timeout`` seconds, answers with something that is not a frame, or
with another number of actions than the batch's episodes ends the evaluation with a one-line error
naming the step (the runner adds the episodes); the chunks written before are kept, and running the same
command again resumes from them.
"""

from __future__ import annotations

import json
import os
import selectors
import shlex
import struct
import subprocess
import tempfile
import time
from typing import Any

import numpy as np

from socialnav.sim.observation import HUMAN_COLUMNS, ROBOT_COLUMNS

__all__ = ["EXEC_PREFIX", "PROTOCOL", "VERSION", "ExecPlanner", "ExecPlannerError"]

#: ``exec:COMMAND`` names a planner program (``socialnav evaluate --policy 'exec:./planner --flag'``).
EXEC_PREFIX = "exec:"
PROTOCOL = "socialnav-exec"
VERSION = 1
#: Binary frames: an observation frame starts with OBS_MAGIC, an action frame with ACT_MAGIC.
OBS_MAGIC = b"SNO1"
ACT_MAGIC = b"SNA1"
#: Observation frame header after the magic: step, B, N, W (int32 each).
_OBS_HEADER = struct.Struct("<4s4i")
_ACT_HEADER = struct.Struct("<4si")


class ExecPlannerError(RuntimeError):
    """The planner program failed: it exited, hung, or answered with something that is not a frame."""


class ExecPlanner:
    """A planner program behind the ``Policy`` interface (module docstring).

    Args:
        command: The program and its arguments, as a shell would split them (no shell runs).
        timeout: Seconds the planner may take to answer the hello and each step.
        kinematics: The robot's kinematics (sent in the hello).
        dt: The step length [s] (sent in the hello).
        robot_limits: What the hello adds about the robot: ``rotation_limit`` [rad] for a unicycle or
            a differential drive, ``diff_drive`` (its acceleration limits and reverse speed) for the latter.
    """

    information = "none"
    #: The evaluation steps it in its own process (workers score): the planning runs in the program, so
    #: simulation workers would only add their start-up and one more planner each.
    simulates_in_process = True

    def __init__(self, command: str, timeout: float = 10.0, kinematics: str = "holonomic", dt: float = 0.25,
                 robot_limits: dict[str, Any] | None = None):
        argv = shlex.split(command)
        if not argv:
            raise ValueError("exec: give the planner's command after 'exec:', e.g. exec:'./planner --fast'")
        if not timeout > 0:
            raise ValueError(f"exec planner timeout must be > 0 s, got {timeout!r}")
        self.command, self.argv, self.timeout = command, argv, float(timeout)
        self.kinematics, self.dt = kinematics, float(dt)
        self.robot_limits = dict(robot_limits or {})
        self.name = EXEC_PREFIX + command
        self.format: str | None = None
        self.planner_name: str | None = None
        self._proc: subprocess.Popen | None = None
        self._stderr: Any = None
        self._step = 0
        self._sent_maps: list[Any] = []

    # -- the process ---------------------------------------------------------------------------------
    def __getstate__(self) -> dict[str, Any]:
        # an evaluation's worker process starts a planner of its own
        state = dict(self.__dict__)
        state.update(_proc=None, _stderr=None, _step=0, _sent_maps=[])
        return state

    def close(self) -> None:
        """Ends the planner (its stdin closed, then terminated if it does not exit within a second)."""
        proc, self._proc = self._proc, None
        if proc is None:
            return
        try:
            if proc.stdin:
                proc.stdin.close()
            proc.wait(timeout=1.0)
        except (OSError, subprocess.TimeoutExpired):
            proc.kill()
            proc.wait()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass

    def _start(self) -> None:
        try:
            # stderr to a file: a talkative planner never blocks on a full pipe, and its last line is kept
            self._stderr = tempfile.TemporaryFile()
            self._proc = subprocess.Popen(self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=self._stderr, bufsize=0)
        except OSError as err:
            raise ExecPlannerError(f"exec planner {self.command!r} could not start: {err}") from None
        self._step = 0
        self._sent_maps = []
        hello = {"protocol": PROTOCOL, "version": VERSION, "kinematics": self.kinematics, "dt": self.dt,
                 "robot_columns": list(ROBOT_COLUMNS["world"]), "human_columns": list(HUMAN_COLUMNS["world"]),
                 "formats": ["json", "binary"], **self.robot_limits}
        self._write((json.dumps(hello) + "\n").encode())
        line = self._read_line("its hello")
        try:
            answer = json.loads(line)
            fmt = answer["format"]
            version = answer.get("version")
        except (ValueError, KeyError, TypeError):
            raise self._fail(f"answered the hello with {line[:120]!r}, not a JSON object with \"format\"") \
                from None
        if answer.get("protocol") != PROTOCOL or version != VERSION:
            raise self._fail(f"speaks protocol {answer.get('protocol')!r} version {version!r}; socialnav "
                             f"speaks {PROTOCOL!r} version {VERSION}")
        if fmt not in ("json", "binary"):
            raise self._fail(f"chose format {fmt!r}; the formats are json and binary")
        self.format = fmt
        self.planner_name = str(answer.get("name")) if answer.get("name") is not None else None

    def _fail(self, what: str) -> ExecPlannerError:
        proc = self._proc
        code = None
        if proc is not None:
            try:  # a planner that closed its output is usually exiting: its code and stderr say why
                code = proc.wait(timeout=0.5)
            except subprocess.TimeoutExpired:
                code = None
        tail = ""
        if code is not None and self._stderr is not None:
            self._stderr.seek(0)
            err = self._stderr.read().decode(errors="replace").strip().splitlines()
            tail = f"; its last stderr line: {err[-1]!r}" if err else ""
        status = "" if code is None else f" (it exited with code {code}{tail})"
        self.close()
        return ExecPlannerError(f"exec planner {self.command!r} {what}{status}")

    def _write(self, data: bytes) -> None:
        assert self._proc is not None and self._proc.stdin is not None
        try:
            self._proc.stdin.write(data)
            self._proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise self._fail(f"stopped reading at step {self._step}") from None

    def _read(self, what: str, size: int | None) -> bytes:
        """``size`` bytes of the planner's output, or up to a newline where ``size`` is None.

        Waits at most ``timeout`` seconds in all; a planner that says nothing for that long, or closes
        its output, fails naming ``what`` it was answering.
        """
        assert self._proc is not None and self._proc.stdout is not None
        fd = self._proc.stdout.fileno()
        deadline = time.monotonic() + self.timeout
        buf = bytearray()
        with selectors.DefaultSelector() as sel:
            sel.register(fd, selectors.EVENT_READ)
            while (len(buf) < size) if size is not None else not buf.endswith(b"\n"):
                left = deadline - time.monotonic()
                if left <= 0 or not sel.select(left):
                    raise self._fail(f"did not answer {what} within {self.timeout:g} s (hung?)")
                chunk = os.read(fd, 65536 if size is None else size - len(buf))
                if not chunk:
                    raise self._fail(f"closed its output before answering {what}")
                buf += chunk
        return bytes(buf)

    def _read_line(self, what: str) -> str:
        buf = self._read(what, None)
        if buf.count(b"\n") > 1:
            raise self._fail(f"answered {what} with more than one line")
        return buf.decode(errors="replace").strip()

    # -- the Policy interface ------------------------------------------------------------------------
    def act(self, observation: Any) -> np.ndarray:
        """The planner's actions (B, 2) for the batch's observation (one exchange).

        Raises:
            ExecPlannerError: The planner exited, hung, answered something that is not an action frame,
                or another number of actions than B (the message names the step).
        """
        if self._proc is None:
            self._start()
        b = observation.batch_size
        walls = self._new_walls(observation)
        self._step += 1
        what = f"step {self._step}"
        if self.format == "json":
            self._write(self._json_frame(observation, walls))
            line = self._read_line(what)
            try:
                actions = np.asarray(json.loads(line)["actions"], dtype=np.float64)
            except (ValueError, KeyError, TypeError):
                expected = '{"actions": [[a0, a1], ...]}'
                raise self._fail(f"answered {what} with {line[:120]!r}, not {expected}") from None
            if actions.shape != (b, 2):
                raise self._fail(f"answered {what} with actions of shape {actions.shape} for a batch of {b} "
                                 "episodes (expected one [a0, a1] per episode)")
            return actions
        self._write(self._binary_frame(observation, walls))
        magic, n = _ACT_HEADER.unpack(self._read(what, _ACT_HEADER.size))
        if magic != ACT_MAGIC:
            raise self._fail(f"answered {what} with {magic!r}, not an action frame ({ACT_MAGIC!r})")
        if n != b:
            raise self._fail(f"answered {what} with {n} actions for a batch of {b} episodes")
        return np.frombuffer(self._read(what, 16 * b), dtype="<f8").reshape(b, 2).astype(np.float64)

    def _new_walls(self, obs: Any) -> dict[int, np.ndarray]:
        """Each row whose map is not the one last sent for it: its wall edges (E, 4)."""
        maps = [None] * obs.batch_size if obs.obstacles is None else list(obs.obstacles.maps)
        if len(self._sent_maps) != len(maps):
            self._sent_maps = [None] * len(maps)
        out = {}
        for row, m in enumerate(maps):
            if m is not self._sent_maps[row]:
                self._sent_maps[row] = m
                out[row] = np.zeros((0, 4)) if not m else np.concatenate(m.edges(), axis=1)
        return out

    def _json_frame(self, obs: Any, walls: dict[int, np.ndarray]) -> bytes:
        frame = {
            "step": self._step,
            "robot": obs.robot.tolist(),
            "humans": obs.humans.tolist(),
            "human_mask": obs.human_mask.astype(int).tolist(),
            "active": obs.active.astype(int).tolist(),
            "time": obs.time.tolist(),
        }
        if walls:
            frame["walls"] = {str(row): edges.tolist() for row, edges in walls.items()}
        if obs.robot_twist is not None:  # a differential drive: the (v, ω) its limits act from
            frame["robot_twist"] = obs.robot_twist.tolist()
        return (json.dumps(frame) + "\n").encode()

    def _binary_frame(self, obs: Any, walls: dict[int, np.ndarray]) -> bytes:
        b, n = obs.humans.shape[:2]
        edges = [np.column_stack([np.full(len(e), row, dtype=np.float64), e]) for row, e in walls.items()]
        wall_rows = np.concatenate(edges) if edges else np.zeros((0, 5))
        parts = [
            _OBS_HEADER.pack(OBS_MAGIC, self._step, b, n, len(wall_rows)),
            np.ascontiguousarray(obs.robot, dtype="<f8").tobytes(),
            np.ascontiguousarray(obs.humans, dtype="<f8").tobytes(),
            np.ascontiguousarray(obs.human_mask, dtype=np.uint8).tobytes(),
            np.ascontiguousarray(obs.active, dtype=np.uint8).tobytes(),
            np.ascontiguousarray(obs.time, dtype="<f8").tobytes(),
            np.ascontiguousarray(wall_rows, dtype="<f8").tobytes(),
        ]
        if obs.robot_twist is not None:  # a differential drive: (v, ω) per row, after the walls
            parts.append(np.ascontiguousarray(obs.robot_twist, dtype="<f8").tobytes())
        return b"".join(parts)

    def describe(self) -> dict[str, Any]:
        """The record stored with results: the command, the protocol version and the planner's name."""
        return {"policy": self.name, "information": self.information, "command": self.command,
                "protocol_version": VERSION, "timeout": self.timeout}
