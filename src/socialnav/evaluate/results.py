"""Reading an evaluation's result directory: its manifest, score rows and stored trajectories.

Episodes are named by a string id ``"<scenario>/<visibility>/<index>"`` (e.g.
``"passing/invisible/3"``); it is also the episode key inside the trajectory files, so
``socialnav metrics RESULTS/trajectories/<cell>/<chunk>.parquet`` reports the same ids. ``render``,
``report`` and ``replay`` all find episodes through :func:`load_episode`.
"""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav.trajectory import Trajectory

_CHUNK = re.compile(r"^(\d+)-(\d+)\.parquet$")


class ResultsError(ValueError):
    """A result directory or an episode id that cannot be used; the message says which and why."""


@dataclass(frozen=True)
class EpisodeRef:
    """Where a stored episode lives."""

    episode_id: str
    scenario: str
    visibility: str
    index: int
    chunk: tuple[int, int]  # [a, b) episode indices of its chunk file
    path: Path  # the chunk's trajectory file


def load_manifest(results_dir: str | Path) -> dict[str, Any]:
    """The run's ``manifest.json``.

    Raises:
        ResultsError: The directory does not exist or holds no manifest (not a result directory).
    """
    root = Path(results_dir)
    if root.is_file():
        raise ResultsError(f"{root}: a file, not a result directory of `socialnav evaluate`")
    if not root.is_dir():
        raise ResultsError(f"{root}: no such result directory")
    path = root / "manifest.json"
    if not path.is_file():
        hint = ""
        for sub, what in (("policies", "`socialnav evaluate --policy all`"), ("evaluate", "a sweep's jobs")):
            if (root / sub).is_dir() and any((root / sub).glob("*/manifest.json")):
                hint = f"; it holds the runs of {what}: pass them, e.g. `socialnav report {root}/{sub}/*`"
        raise ResultsError(f"{root}: not a result directory of `socialnav evaluate` (no manifest.json){hint}")
    try:
        manifest = json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ResultsError(f"{path}: not valid JSON ({err})") from None
    if not isinstance(manifest, dict) or not isinstance(manifest.get("policy"), dict) or not isinstance(
            manifest.get("cells"), list):
        raise ResultsError(f"{path}: not a manifest of `socialnav evaluate` (expected an object with "
                           "'policy' and 'cells')")
    return manifest


def parse_episode_id(episode_id: str) -> tuple[str, str, int]:
    """Splits ``"scenario/visibility/index"``; raises :class:`ResultsError` on another form."""
    parts = str(episode_id).split("/")
    if len(parts) != 3 or not parts[2].isdigit() or not parts[0] or not parts[1]:
        raise ResultsError(
            f"episode id {episode_id!r} is not of the form <scenario>/<visibility>/<index>, "
            "e.g. passing/invisible/3"
        )
    return parts[0], parts[1], int(parts[2])


def _chunks(results_dir: Path) -> dict[str, list[tuple[int, int, Path]]]:
    """Stored trajectory chunks per cell key (``scenario__visibility``), sorted by first index."""
    base = results_dir / "trajectories"
    if not base.is_dir():
        manifest = load_manifest(results_dir)
        why = (
            "the run was made with --no-trajectories"
            if manifest.get("trajectories") is False
            else "the run was made before trajectories were kept, or has not finished a chunk yet"
        )
        raise ResultsError(
            f"{results_dir}: no stored trajectories ({why}); run `socialnav evaluate` again into a new "
            "--out directory to keep them"
        )
    cells: dict[str, list[tuple[int, int, Path]]] = {}
    for cell_dir in sorted(p for p in base.iterdir() if p.is_dir()):
        found = []
        for f in cell_dir.iterdir():
            m = _CHUNK.match(f.name)
            if m and (results_dir / "episodes" / cell_dir.name / f.name).is_file():
                found.append((int(m.group(1)), int(m.group(2)), f))  # done: scores exist too
        if found:
            cells[cell_dir.name] = sorted(found)
    return cells


def _cell_order(results_dir: Path, keys: list[str]) -> list[str]:
    # The manifest's cell order (the order the run used), then anything else found on disk.
    try:
        listed = [f"{c['scenario']}__{c['visibility']}" for c in load_manifest(results_dir).get("cells", [])]
    except (ResultsError, KeyError, TypeError):
        listed = []
    return [k for k in listed if k in keys] + sorted(k for k in keys if k not in listed)


def list_episodes(results_dir: str | Path) -> list[str]:
    """Ids of every stored episode, in the run's cell order, then by index.

    Raises:
        ResultsError: Not a result directory, or it holds no trajectories.
    """
    root = Path(results_dir)
    cells = _chunks(root)
    ids = []
    for key in _cell_order(root, list(cells)):
        scenario, visibility = key.split("__", 1)
        for a, b, _ in cells[key]:
            ids.extend(f"{scenario}/{visibility}/{i}" for i in range(a, b))
    return ids


def find_episode(results_dir: str | Path, episode_id: str) -> EpisodeRef:
    """Locates a stored episode; errors list what exists."""
    root = Path(results_dir)
    scenario, visibility, index = parse_episode_id(episode_id)
    cells = _chunks(root)
    key = f"{scenario}__{visibility}"
    if key not in cells:
        have = ", ".join(k.replace("__", "/") for k in _cell_order(root, list(cells))) or "none"
        raise ResultsError(
            f"{root}: no stored episodes of {scenario}/{visibility}; stored scenario/visibility: {have}"
        )
    for a, b, path in cells[key]:
        if a <= index < b:
            return EpisodeRef(f"{scenario}/{visibility}/{index}", scenario, visibility, index, (a, b), path)
    ranges = ", ".join(f"{a}..{b - 1}" for a, b, _ in cells[key])
    raise ResultsError(
        f"{root}: episode {episode_id!r} is not stored; {scenario}/{visibility} has indices {ranges}"
    )


def load_episode(results_dir: str | Path, episode_id: str) -> Trajectory:
    """The stored trajectory of one evaluated episode (``settings["episode"]`` is its id).

    Raises:
        ResultsError: Unknown directory, id or episode (the message lists what exists).
    """
    from socialnav.trajectory_io import read_trajectories

    ref = find_episode(results_dir, episode_id)
    found = read_trajectories(ref.path, episodes=[ref.episode_id])
    if len(found) != 1:
        raise ResultsError(f"{ref.path}: episode {ref.episode_id!r} missing from its chunk file")
    return found[0]


def load_episode_rows(results_dir: str | Path) -> list[dict[str, Any]]:
    """Every scored episode row (``episodes/<cell>/<chunk>.parquet``), each with its ``episode_id``."""
    import pyarrow.parquet as pq

    root = Path(results_dir)
    load_manifest(root)
    rows: list[dict[str, Any]] = []
    base = root / "episodes"
    files = sorted(base.glob("*/*.parquet")) if base.is_dir() else []
    for path in files:
        for row in pq.read_table(path).to_pylist():
            row["episode_id"] = f"{row['scenario']}/{row['visibility']}/{row['index']}"
            rows.append(row)
    return rows
