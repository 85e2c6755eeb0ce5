"""The protocol runner: simulate every cell of a preset with one policy, score, aggregate, write.

Results live in an output directory:

    manifest.json                  what was run (preset, policy, cells); checked on resume
    episodes/<cell>/<a>-<b>.parquet  one row per episode (ids, outcome, every metric), atomic
    trajectories/<cell>/<a>-<b>.parquet  every episode's trajectory (docs/trajectory_format.md), unless
                                   trajectories=False; episode keys "<scenario>/<visibility>/<index>"
    summary.json / summary.csv     per (policy, scenario, visibility) and pooled aggregates
    table2.md / table2.tex         the paper's Table II layout (+ per-scenario tables)
    table3.md / table3.tex         the paper's Table III layout (M_VI side preference)

A chunk file is written only when all its episodes are scored, so an interrupted run resumes by
skipping the chunk files that exist: nothing finished is recomputed or lost. Every chunk file carries
the fingerprint of the manifest it was computed for and Parquet page checksums; a file of another
run, or a damaged one, is refused by name instead of being scored. A run holds ``.lock`` in the
directory while it writes there: a second run on the same directory is refused at once. With
trajectories, the trajectory file is written first and a chunk counts as done only when both files
exist; a chunk that has one without the other is simulated again (episodes are deterministic, so both
are rewritten identically).

The work is split by job: :mod:`~socialnav.evaluate.manifest` (what a run is, its fingerprint, the
resume decision), :mod:`~socialnav.evaluate.execution` (simulating and scoring chunks, in this process
or in workers) and :mod:`~socialnav.evaluate.chunks` (the chunk files). A sweep uses the same three.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from socialnav._io import DirectoryLock, make_output_dir
from socialnav._runtime import one_blas_thread
from socialnav.evaluate.chunks import ResumeMismatchError, chunk_path, read_chunk, read_episode_rows
from socialnav.evaluate.execution import compute_chunks, validate_cells
from socialnav.evaluate.manifest import manifest_stamp, protocol_manifest, refuse_other_kind, resume_directory
from socialnav.evaluate.plan import Cell, multi_human_scenarios, plan_cells
from socialnav.evaluate.report import mismatch_caveats, render_reports, write_reports
from socialnav.evaluate.summary import summarize_episodes
from socialnav.policies.registry import Policy, missing_policy_members
from socialnav.presets import Preset

__all__ = ["ProtocolResult", "ResumeMismatchError", "conclude_chunks", "run_protocol"]


@dataclass(frozen=True)
class ProtocolResult:
    """What :func:`run_protocol` returns.

    Attributes:
        out_dir: The result directory.
        rows: One row per episode (ids, outcome, every metric), in cell and index order.
        summary: The aggregate rows (per scenario and visibility, and pooled).
        computed_episodes: Episodes simulated by this call (0 when everything was resumed).
    """

    out_dir: Path
    rows: list[dict[str, Any]]
    summary: list[dict[str, Any]]
    computed_episodes: int


def run_protocol(
    policy: Policy,
    preset: Preset | str,
    out_dir: str | Path,
    *,
    label: str | None = None,
    scenarios: Sequence[str] | None = None,
    episodes: int | None = None,
    visibility: str | None = None,
    progress: bool = True,
    extra_manifest: dict | None = None,
    batch_size: int = 256,
    workers: int | None = None,
    trajectories: bool = True,
    simulate_in_workers: bool | None = None,
) -> ProtocolResult:
    """Runs (or resumes) the protocol of ``preset`` for ``policy`` and writes every result file.

    Args:
        policy: The robot policy (an object with ``name``, ``act`` and ``describe``).
        preset: The protocol (world, robot, scenarios, episode counts), or a shipped preset's name or a
            YAML file's path (as ``load_preset`` takes).
        out_dir: Result directory; an existing one with the same manifest is resumed.
        label: Policy name in the results (default ``policy.name``).
        scenarios: Only these scenarios (default: the preset's); one name may be given as a string.
        episodes: Episodes per multi-human scenario (an integer; default: the preset's).
        visibility: ``invisible``, ``visible`` or ``both`` (default: the preset's).
        progress: Show a progress bar on stderr.
        extra_manifest: Extra fields recorded in the manifest (e.g. the checkpoint path).
        batch_size: Episodes simulated in lockstep.
        workers: Processes that score finished chunks while the next chunk is simulated (default:
            one per core, at most 4; 0 scores in this process). Called from the top level of a
            script without an ``if __name__ == "__main__":`` guard, scoring stays in this process
            (workers would re-run the script).
        trajectories: Keep every episode's trajectory under ``trajectories/`` (for ``socialnav
            replay``, ``render`` and ``report``).
        simulate_in_workers: Simulate chunks in the worker processes too, one torch thread each
            (default: when the policy can be pickled, i.e. learned policies). Each chunk is simulated
            exactly as in this process (same slots, same batches), so results are bit-identical; on
            few cores, one process per core beats intra-op threads on the small batches of a
            draining chunk (docs/protocol.md).

    Returns:
        The episode rows, the summary and how many episodes this call computed.

    Raises:
        ResumeMismatchError: ``out_dir`` holds a different run's results.
        TypeError: ``policy`` is not a policy, ``preset`` not a preset, or ``episodes`` not an integer.
    """
    from socialnav.presets import load_preset

    missing = missing_policy_members(policy)
    if missing:
        raise TypeError(f"policy must have name, act(observation) and describe() "
                        f"(docs/custom_policies.md); a {type(policy).__name__} has no {', '.join(missing)}")
    if isinstance(preset, str | Path):
        preset = load_preset(preset)
    elif not isinstance(preset, Preset):
        raise TypeError(f"preset must be a Preset or a preset's name or file, got a "
                        f"{type(preset).__name__}")
    if isinstance(scenarios, str):
        scenarios = [scenarios]
    if episodes is not None and (isinstance(episodes, bool) or not hasattr(episodes, "__index__")):
        raise TypeError(f"episodes must be an integer, got {episodes!r}")
    out = Path(out_dir)
    label = label or policy.name
    cells = plan_cells(preset, list(scenarios) if scenarios else None, episodes, visibility)
    chunk_size = preset.evaluation.chunk_size
    # Everything that can be refused is refused before the first file is written.
    validate_cells(preset, cells, batch_size)
    manifest = protocol_manifest(policy, preset, cells, label, batch_size, trajectories, extra_manifest)
    if getattr(policy, "built_for_preset", None) != preset.name:  # build_policy applied them
        _say_preset_policy_settings_unused(manifest["policy"], preset)
    stamp = manifest_stamp(manifest)
    refuse_other_kind(out, "one policy")
    make_output_dir(out)
    # Worker processes are the parallelism; the bootstrap's small products need one BLAS thread
    # (socialnav/_runtime.py), and spinning BLAS threads would take CPU from the workers.
    with DirectoryLock(out, "evaluation"), one_blas_thread():
        plan = resume_directory(out, manifest, cells, chunk_size, trajectories)
        # Damaged or foreign chunk files are refused now, before anything is computed.
        verified = {
            chunk_path(out, cell, a, b): read_chunk(chunk_path(out, cell, a, b), cell, a, b, label, stamp)
            for cell, a, b in plan.done
        }
        computed = compute_chunks(
            policy, preset, out, plan.todo, label, stamp, sum(c.episodes for c in cells), progress,
            batch_size, workers, trajectories, simulate_in_workers,
        )
        rows = read_episode_rows(out, cells, chunk_size, label, stamp, verified)
        summary = summarize_episodes(rows, multi_human=multi_human_scenarios(cells))
        write_reports(out, summary, rows, preset, mismatch_caveats(manifest["policy"]))
    return ProtocolResult(out, rows, summary, computed)


def _say_preset_policy_settings_unused(record: dict[str, Any], preset: Preset) -> None:
    """Warns where the policy runs with other settings than the preset's ``policies`` section gives it.

    ``socialnav evaluate`` builds the policy with them (``build_policy(name, preset)``); a policy built
    in Python with ``make_policy`` has the registry's defaults, and the run would not be the CLI's.
    """
    wanted = preset.policies.get(str(record.get("policy")), {})
    differ = [f"{k} = {record[k]!r} (the preset: {v!r})" for k, v in wanted.items()
              if k in record and record[k] != v]
    if differ:
        warnings.warn(
            f"policy {record['policy']!r} runs with {', '.join(differ)}: preset {preset.name!r} sets these "
            "for it (policies section), as `socialnav evaluate` would apply; build it with "
            "build_policy(name, preset) to use them", UserWarning, stacklevel=3,
        )


def conclude_chunks(
    chunks: Sequence[tuple[Cell, int, int, str, bytes]],
    label: str | None,
    stamp: str | None,
    preset: Preset,
) -> tuple[int, list[dict[str, Any]], dict[str, str]]:
    """A finished run's conclusion from its chunk files' bytes.

    A sweep computes it in a worker, which may have no access to the result directory.

    Args:
        chunks: ``(cell, start, stop, path, bytes)`` of every chunk, in cell and index order
            (``path`` names a chunk in errors).
        label: The policy label every row must carry (None: not checked).
        stamp: The manifest fingerprint every chunk must carry (None: not checked).
        preset: The protocol.

    Returns:
        The number of episodes, the summary rows and the text of every result file by name, as
        :func:`run_protocol` writes them.

    Raises:
        ResumeMismatchError: A chunk belongs to another run.
        CorruptFileError: A chunk is damaged.
    """
    rows: list[dict[str, Any]] = []
    for cell, a, b, path, data in chunks:
        rows.extend(read_chunk(Path(path), cell, a, b, label, stamp, data))
    summary = summarize_episodes(rows, multi_human=multi_human_scenarios([c[0] for c in chunks]))
    return len(rows), summary, render_reports(summary, preset)
