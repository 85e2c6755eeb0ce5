"""The chunk store of a result directory: where chunk files live, how they are stamped and read back.

A cell's episodes are computed in chunks of ``chunk_size`` episodes. Each chunk has two files, named by
its episode range ``[a, b)``::

    episodes/<cell>/<a>-<b>.parquet      one row per episode (ids, outcome, every metric)
    trajectories/<cell>/<a>-<b>.parquet  every episode's trajectory (docs/trajectory_format.md), when
                                         the run keeps trajectories

An episode file carries, in its Parquet metadata, the fingerprint of the manifest of the run that wrote
it (:data:`CHUNK_STAMP_KEY`) and Parquet page checksums, so a file of another run, or a damaged one, is
refused by name instead of being scored. Both the protocol runner and a sweep read and write chunks
through this module, so their directories are interchangeable.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from socialnav._io import (
    atomic_write_bytes,
    atomic_write_rows_parquet,
    read_parquet_verified,
    rows_parquet_bytes,
)
from socialnav.evaluate.plan import Cell

#: Parquet metadata key of a chunk file: the fingerprint of the manifest of the run that wrote it.
CHUNK_STAMP_KEY = "socialnav.manifest"

#: A chunk: its cell and its episode range ``[start, stop)``.
Chunk = tuple[Cell, int, int]

_DELETE_TO_RECOMPUTE = "delete it to recompute those episodes"


class ResumeMismatchError(RuntimeError):
    """The output directory holds results of a different run configuration."""


def chunk_path(out: Path, cell: Cell, start: int, stop: int) -> Path:
    """The episode file of a chunk.

    Args:
        out: The result directory.
        cell: The chunk's cell.
        start: Its first episode index.
        stop: One past its last episode index.

    Returns:
        ``out/episodes/<cell key>/<start:05d>-<stop:05d>.parquet``.
    """
    return out / "episodes" / _chunk_file_name(cell, start, stop)


def trajectory_path(out: Path, cell: Cell, start: int, stop: int) -> Path:
    """The trajectory file of a chunk, named like its episode file under ``trajectories/``.

    Args:
        out: The result directory.
        cell: The chunk's cell.
        start: Its first episode index.
        stop: One past its last episode index.

    Returns:
        ``out/trajectories/<cell key>/<start:05d>-<stop:05d>.parquet``.
    """
    return out / "trajectories" / _chunk_file_name(cell, start, stop)


def _chunk_file_name(cell: Cell, start: int, stop: int) -> Path:
    # One naming scheme for a chunk's episode and trajectory files, so that they always pair up.
    return Path(cell.key) / f"{start:05d}-{stop:05d}.parquet"


def chunk_done(out: Path, cell: Cell, start: int, stop: int, trajectories: bool) -> bool:
    """Whether a chunk is finished: its episode file exists, and its trajectory file if kept.

    The trajectory file is written first, so a chunk with only one of the two was interrupted and is
    simulated again (episodes are deterministic: both files are rewritten identically).

    Args:
        out: The result directory.
        cell: The chunk's cell.
        start: Its first episode index.
        stop: One past its last episode index.
        trajectories: Whether the run keeps trajectories.

    Returns:
        True when nothing of the chunk is left to compute.
    """
    return chunk_path(out, cell, start, stop).exists() and (
        not trajectories or trajectory_path(out, cell, start, stop).exists()
    )


def write_chunk(out: Path, cell: Cell, start: int, stop: int, rows: list[dict[str, Any]], stamp: str) -> None:
    """Writes a chunk's episode rows atomically, stamped with the run they belong to.

    Args:
        out: The result directory.
        cell: The chunk's cell.
        start: Its first episode index.
        stop: One past its last episode index.
        rows: One row per episode, in index order.
        stamp: The run's manifest fingerprint (:func:`socialnav.evaluate.manifest.manifest_stamp`).
    """
    atomic_write_rows_parquet(chunk_path(out, cell, start, stop), rows, {CHUNK_STAMP_KEY: stamp})


def store_chunk_files(
    out: Path, cell: Cell, start: int, stop: int, episode_file: bytes, trajectory_file: bytes | None
) -> None:
    """Stores a chunk computed elsewhere (a sweep's worker), as :func:`write_chunk` would.

    The trajectory file lands first: a chunk counts as done once its episode file exists
    (:func:`chunk_done`).

    Args:
        out: The result directory.
        cell: The chunk's cell.
        start: Its first episode index.
        stop: One past its last episode index.
        episode_file: The episode file's bytes (:func:`chunk_file_bytes`).
        trajectory_file: The trajectory file's bytes, or None when the run keeps no trajectories.
    """
    if trajectory_file is not None:
        atomic_write_bytes(trajectory_path(out, cell, start, stop), trajectory_file)
    atomic_write_bytes(chunk_path(out, cell, start, stop), episode_file)


def chunk_file_bytes(rows: list[dict[str, Any]], stamp: str) -> bytes:
    """The bytes :func:`write_chunk` would write, for a worker that has no access to the directory.

    Args:
        rows: One row per episode, in index order.
        stamp: The run's manifest fingerprint.

    Returns:
        The Parquet file's bytes.
    """
    return rows_parquet_bytes(rows, {CHUNK_STAMP_KEY: stamp})


def read_chunk(
    path: Path,
    cell: Cell,
    start: int,
    stop: int,
    label: str | None,
    stamp: str | None,
    data: bytes | None = None,
) -> list[dict[str, Any]]:
    """The rows of a chunk file, refused if damaged or not this run's.

    Args:
        path: The chunk's episode file (read unless ``data`` is given; named in errors).
        cell: The cell it must hold.
        start: The first episode index it must hold.
        stop: One past the last episode index it must hold.
        label: The policy label its rows must carry (None: not checked).
        stamp: The manifest fingerprint it must carry (None: not checked).
        data: The file's bytes, when already in memory.

    Returns:
        One row per episode, in index order.

    Raises:
        ResumeMismatchError: The file belongs to another run, cell or policy, or lacks episodes.
        CorruptFileError: The file is damaged or not Parquet.
    """
    table = read_parquet_verified(path, data=data)
    if stamp is not None:
        got = (table.schema.metadata or {}).get(CHUNK_STAMP_KEY.encode(), b"").decode(errors="replace")
        if got != stamp:
            raise ResumeMismatchError(
                f"{path} does not belong to this run (written for another configuration"
                f"{'' if got else ' or by an older socialnav'}); {_DELETE_TO_RECOMPUTE}"
            )
    rows = table.to_pylist()
    expected = (("scenario", cell.scenario), ("visibility", cell.visibility), ("policy", label))
    bad = next(
        ((k, r.get(k), v) for r in rows for k, v in expected if v is not None and r.get(k) != v), None
    )
    if bad is not None:
        raise ResumeMismatchError(
            f"{path} holds {bad[0]} {bad[1]!r}, expected {bad[2]!r}; {_DELETE_TO_RECOMPUTE}"
        )
    if [r.get("index") for r in rows] != list(range(start, stop)):
        raise ResumeMismatchError(
            f"{path} does not hold episodes {start}..{stop - 1} in order; {_DELETE_TO_RECOMPUTE}"
        )
    return rows


def read_episode_rows(
    out: Path,
    cells: list[Cell],
    chunk_size: int,
    label: str | None = None,
    stamp: str | None = None,
    verified: dict[Path, list[dict[str, Any]]] | None = None,
) -> list[dict[str, Any]]:
    """Every episode row of a run, in cell and index order.

    Args:
        out: The result directory.
        cells: The run's cells.
        chunk_size: Episodes per chunk.
        label: The policy label every row must carry (None: not checked).
        stamp: The manifest fingerprint every chunk must carry (None: not checked).
        verified: Rows of chunks already read and checked in this run, by path (not read again).

    Returns:
        One row per episode.

    Raises:
        ResumeMismatchError: A chunk belongs to another run.
        CorruptFileError: A chunk is damaged.
    """
    rows: list[dict[str, Any]] = []
    known = verified or {}
    for cell in cells:
        for a, b in cell.chunks(chunk_size):
            path = chunk_path(out, cell, a, b)
            rows.extend(known[path] if path in known else read_chunk(path, cell, a, b, label, stamp))
    return rows


def refuse_foreign_chunks(out: Path, expected: dict[Path, Any]) -> None:
    """Refuses a directory holding episode files that are not chunks of this run.

    Args:
        out: The result directory.
        expected: This run's chunk episode files (as keys).

    Raises:
        ResumeMismatchError: Naming the first foreign file and how many more there are.
    """
    episodes = out / "episodes"
    if not episodes.is_dir():
        return
    foreign = sorted(p for p in episodes.rglob("*.parquet") if p not in expected)
    if foreign:
        more = f" and {len(foreign) - 1} more" if len(foreign) > 1 else ""
        raise ResumeMismatchError(
            f"{foreign[0]}{more} in {episodes} is not part of this run; move it away or use another --out"
        )


def has_results(out: Path) -> bool:
    """Whether the directory holds any episode file (a manifest alone blocks no other run).

    Args:
        out: The result directory.

    Returns:
        True when ``out/episodes`` holds a Parquet file.
    """
    return (out / "episodes").is_dir() and any((out / "episodes").rglob("*.parquet"))
