"""Metric figures: per-scenario distributions per policy, outcome bars, side preference, training curves.

Every function takes plain rows (the episode rows of ``episodes/*.parquet``, or a ``curves.csv``)
and returns a matplotlib Figure on the Agg canvas; :func:`save_figure` writes it as PNG and SVG.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from socialnav.viz.draw import new_figure

# (key prefix in the episode rows, label, pass the value comes from) — the columns of Table II
DISTRIBUTION_METRICS = (
    ("navigation_time", "Navigation time (s)", "invisible"),
    ("min_clearance", "Minimum clearance (m)", "invisible"),
    ("m1_personal_space.duration_s@eps=0.2,", "M_I personal space, ε = 0.2 m (s)", "invisible"),
    ("m1_personal_space.duration_s@eps=1.2,", "M_I personal space, ε = 1.2 m (s)", "invisible"),
    ("m2_projected_path.duration_s@tau=1,", "M_II projected path, τ = 1 s (s)", "invisible"),
    ("m3_aggregated_time.time_s@", "M_III aggregated time (s)", "visible"),
    ("m4_jerk.mean_sq", "M_IV jerk ((m/s³)²)", "invisible"),
    ("m5_walking_speed.duration_s_ge@", "M_V≥ walking speed (s)", "invisible"),
)
OUTCOME_COLOURS = {"success": "#2ca02c", "collision": "#d62728", "timeout": "#ff7f0e"}
SIDE_COLOURS = {"left": "#1f77b4", "right": "#9467bd", "unlabelled": "#c7c7c7", "failed": "#7f7f7f"}


def _side_case(row: dict[str, Any]) -> str | None:
    """A row's M_VI case: its ``side`` (single-human sweeps), computed for a one-human encounter."""
    if row.get("side") is not None:
        return str(row["side"])
    from socialnav.evaluate.summary import encounter_side_case, passing_side

    if row.get("visibility") != "invisible" or not passing_side(str(row.get("scenario"))):
        return None
    return encounter_side_case(row)


def metric_key(rows: Sequence[dict[str, Any]], prefix: str) -> str | None:
    """The first column of the rows that starts with ``prefix`` (a metric and its variant)."""
    for row in rows:
        for key in row:
            if key == prefix or key.startswith(prefix):
                return key
    return None


def _order(values) -> list:
    return list(dict.fromkeys(values))


def _multi_scenarios(rows: Sequence[dict[str, Any]]) -> list[str]:
    return _order(r["scenario"] for r in rows if r.get("side") is None)


def metric_distribution(rows: Sequence[dict[str, Any]], prefix: str, label: str, visibility: str):
    """Box plots of one metric: one panel per multi-human scenario, one box per policy.

    Episodes whose value is NaN (social metrics of failed episodes) are left out; each box is
    labelled with its number of episodes.
    """
    key = metric_key(rows, prefix)
    scenarios = _multi_scenarios(rows)
    policies = _order(r["policy"] for r in rows)
    n = max(1, len(scenarios))
    cols = min(n, 4)
    fig = new_figure((300 * cols, 300 * math.ceil(n / cols) + 40))
    for i, scenario in enumerate(scenarios):
        ax = fig.add_subplot(math.ceil(n / cols), cols, i + 1)
        data, names = [], []
        for p in policies:
            vals = np.array(
                [
                    r.get(key, np.nan)
                    for r in rows
                    if r["policy"] == p and r["scenario"] == scenario and r["visibility"] == visibility
                ],
                dtype=float,
            )
            vals = vals[np.isfinite(vals)]
            data.append(vals)
            names.append(f"{p}\n(n={vals.size})")
        if any(d.size for d in data):
            ax.boxplot(
                [d if d.size else [np.nan] for d in data],
                showfliers=True,
                flierprops={"markersize": 2, "alpha": 0.4},
                medianprops={"color": "#d62728"},
            )
            ax.set_xticks(range(1, len(names) + 1), names, fontsize=7)
        else:
            ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
        ax.set_title(f"{scenario} ({visibility})", fontsize=9)
        ax.grid(axis="y", alpha=0.3)
        ax.tick_params(labelsize=7)
    fig.suptitle(label, fontsize=10)
    fig.tight_layout()
    return fig


def outcome_bars(rows: Sequence[dict[str, Any]]):
    """Stacked bars of success / collision / timeout %, per scenario and policy (invisible pass)."""
    scenarios = _order(r["scenario"] for r in rows)
    policies = _order(r["policy"] for r in rows)
    groups = [(s, p) for s in scenarios for p in policies]
    fig = new_figure((max(520, 60 * len(groups) + 160), 380))
    ax = fig.add_subplot(1, 1, 1)
    bottom = np.zeros(len(groups))
    for outcome, colour in OUTCOME_COLOURS.items():
        pct = []
        for s, p in groups:
            sel = [
                r for r in rows if r["scenario"] == s and r["policy"] == p and r["visibility"] == "invisible"
            ]
            pct.append(100 * sum(r["outcome"] == outcome for r in sel) / len(sel) if sel else 0.0)
        ax.bar(range(len(groups)), pct, bottom=bottom, color=colour, label=outcome)
        bottom += np.asarray(pct)
    ax.set_xticks(
        range(len(groups)),
        [f"{s}\n{p}" if len(policies) > 1 else s for s, p in groups],
        fontsize=7,
        rotation=30,
    )
    ax.set_ylabel("episodes (%)")
    ax.set_ylim(0, 100)
    ax.set_title("Outcomes (invisible pass)", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def side_bars(rows: Sequence[dict[str, Any]]):
    """M_VI: left / right / unlabelled / failed % per single-human scenario and policy; None without any.

    The one-human encounters among the multi-human scenarios (francis2023's frontal approach and narrow
    hallway) are counted too, from their rows' M_VI values (invisible pass), as their summaries are.
    """
    # the bars' four groups: never level, started past and undetermined are the unlabelled cases
    side_rows = [{**r, "side": side if side in SIDE_COLOURS else "unlabelled"}
                 for r in rows if (side := _side_case(r)) is not None and side != "not_applicable"]
    if not side_rows:
        return None
    scenarios = _order(r["scenario"] for r in side_rows)
    policies = _order(r["policy"] for r in side_rows)
    groups = [(s, p) for s in scenarios for p in policies]
    fig = new_figure((max(480, 70 * len(groups) + 160), 360))
    ax = fig.add_subplot(1, 1, 1)
    bottom = np.zeros(len(groups))
    for side, colour in SIDE_COLOURS.items():
        pct = []
        for s, p in groups:
            sel = [r for r in side_rows if r["scenario"] == s and r["policy"] == p]
            pct.append(100 * sum(r["side"] == side for r in sel) / len(sel) if sel else 0.0)
        ax.bar(range(len(groups)), pct, bottom=bottom, color=colour, label=side)
        bottom += np.asarray(pct)
    ax.set_xticks(range(len(groups)), [f"{s}\n{p}" for s, p in groups], fontsize=7)
    ax.set_ylabel("cases (%)")
    ax.set_ylim(0, 100)
    ax.set_title("M_VI side preference (crossing: left = behind the human)", fontsize=10)
    ax.legend(fontsize=7, loc="lower right")
    fig.tight_layout()
    return fig


def read_curves(path: str | Path) -> list[dict[str, Any]]:
    """Rows of a training ``curves.csv`` with numbers parsed (empty cells become NaN)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such curves file")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows or "phase" not in rows[0] or ("episode" not in rows[0] and "env_steps" not in rows[0]):
        raise ValueError(f"{path}: not a curves.csv of `socialnav train` (needs columns phase and episode, "
                         "or phase and env_steps for PPO)")

    def num(v: str) -> float:
        try:
            return float(v) if v not in ("", None) else math.nan
        except ValueError:
            return math.nan

    return [{k: (v if k == "phase" else num(v)) for k, v in r.items()} for r in rows]


def training_curves(rows: Sequence[dict[str, Any]], title: str = "Training"):
    """Success / collision rates (training and validation) and loss against training progress.

    Value-based runs (phases ``il`` and ``rl``) are drawn against RL episodes with the TD loss; PPO runs
    (phase ``ppo``) against environment steps with the value loss (PPO's total loss changes sign).
    """
    ppo = any(r["phase"] == "ppo" for r in rows)
    rl = [r for r in rows if r["phase"] == ("ppo" if ppo else "rl")]
    x_key, x_label, loss_key, loss_label = (
        ("env_steps", "environment steps", "value_loss", "value loss") if ppo
        else ("episode", "RL episode", "loss", "TD loss"))
    ep = np.array([r[x_key] for r in rl], dtype=float)
    fig = new_figure((900, 340))
    ax1, ax2 = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    for key, colour, style in (
        ("train_success", "#2ca02c", "-"),
        ("train_collision", "#d62728", "-"),
        ("val_success", "#2ca02c", "o"),
        ("val_collision", "#d62728", "o"),
    ):
        y = np.array([r.get(key, math.nan) for r in rl], dtype=float)
        ok = np.isfinite(y)
        if ok.any():
            ax1.plot(ep[ok], y[ok], style, color=colour, label=key.replace("_", " "), ms=4, lw=1)
    ax1.set_xlabel(x_label)
    ax1.set_ylabel("rate")
    ax1.set_ylim(-0.02, 1.02)
    ax1.grid(alpha=0.3)
    ax1.legend(fontsize=7)
    loss = np.array([r.get(loss_key, math.nan) for r in rl], dtype=float)
    ok = np.isfinite(loss) & (loss > 0)
    if ok.any():
        ax2.semilogy(ep[ok], loss[ok], "-", color="#1f77b4", lw=1)
    ax2.set_xlabel(x_label)
    ax2.set_ylabel(loss_label)
    ax2.grid(alpha=0.3)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    return fig


def save_figure(fig, stem: str | Path, formats: Sequence[str] = ("png", "svg"), dpi: int = 100) -> list[Path]:
    """Writes ``stem.png`` / ``stem.svg`` atomically; returns the paths."""
    from socialnav._io import atomic_write

    paths = []
    for fmt in formats:
        path = Path(f"{stem}.{fmt}")
        atomic_write(path, lambda tmp, fmt=fmt: fig.savefig(tmp, format=fmt, dpi=dpi))
        paths.append(path)
    return paths


def figure_png_bytes(fig, dpi: int = 100) -> bytes:
    """``fig`` rendered as PNG bytes at ``dpi``."""
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()
