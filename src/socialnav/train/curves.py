"""``curves.csv`` of a training run and optional TensorBoard scalars.

The file is appended to, and trimmed to the resumed episode (or update) when a run resumes.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

from socialnav._io import atomic_write_text

#: The value-based trainer's columns (a trainer passes its own to :class:`Curves`).
CURVE_COLUMNS = (
    "phase",
    "episode",
    "epsilon",
    "train_episodes",
    "train_success",
    "train_collision",
    "train_timeout",
    "loss",
    "val_success",
    "val_collision",
    "val_timeout",
    "val_nav_time",
    "predictor_loss",
    "gradient_steps",
    "transitions",
    "wall_time",
)


def window_columns(rates: dict[str, float], episodes: int) -> dict[str, Any]:
    """A row's columns for the training episodes of the window it closes (rates empty without any)."""
    if episodes == 0:  # no episode ended in the window: no rate, not a rate of 0
        return {"train_episodes": 0}
    return {
        "train_episodes": episodes,
        "train_success": rates["success"],
        "train_collision": rates["collision"],
        "train_timeout": rates["timeout"],
    }


def validation_columns(val: dict[str, Any] | None) -> dict[str, Any]:
    """A row's columns for the validation it reports (none without one)."""
    if val is None:
        return {}
    return {
        "val_success": val["success"],
        "val_collision": val["collision"],
        "val_timeout": val["timeout"],
        "val_nav_time": val["nav_time"],
    }


class Curves:
    """curves.csv (appended) and optional TensorBoard scalars."""

    def __init__(
        self,
        path: Path,
        resume_episode: int | None,
        columns: tuple[str, ...] = CURVE_COLUMNS,
        key: str = "episode",
    ) -> None:
        """Opens (creates, or trims on resumption) the run's curves.csv.

        Args:
            path: curves.csv.
            resume_episode: the resumed checkpoint's counter (rows after it are dropped), or None
                for a fresh run (the file is started anew).
            columns: the CSV's columns.
            key: the counter rows are trimmed by on resumption (``episode`` for the value-based
                trainer's rows of phase ``rl``, its imitation's ``il`` rows kept; ``update`` for every
                row of PPO's, its imitation's ``il`` rows too).
        """
        self.path = path
        self.columns = columns
        self.dropped = 0  # damaged rows left out on resumption
        if resume_episode is not None and path.exists():  # drop rows written after the resumed checkpoint
            with open(path, newline="", encoding="utf-8", errors="replace") as f:
                rows = []
                for r in csv.DictReader(f):
                    episode = row_episode(r, key)
                    if episode is None:
                        self.dropped += 1  # a damaged row (e.g. cut short by a kill) is not fatal
                    elif (key != "update" and r["phase"] not in ("rl", "ppo")) or episode <= resume_episode:
                        rows.append(r)
            lines = [",".join(columns)] + [",".join(r.get(c, "") for c in columns) for r in rows]
            atomic_write_text(path, "\n".join(lines) + "\n")
        elif not path.exists() or resume_episode is None:
            atomic_write_text(path, ",".join(columns) + "\n")
        self.tb = None
        try:
            from torch.utils.tensorboard import SummaryWriter

            self.tb = SummaryWriter(str(path.parent / "tb"))
        except Exception:  # tensorboard is optional
            self.tb = None

    def write(self, row: dict[str, Any]) -> None:
        """Appends one row (missing columns and NaN empty) and its TensorBoard scalars.

        Args:
            row: column → value.
        """
        def fmt(v: Any) -> str:
            if v is None or (isinstance(v, float) and math.isnan(v)):
                return ""
            return f"{v:.6g}" if isinstance(v, float) else str(v)

        with open(self.path, "a", newline="") as f:
            f.write(",".join(fmt(row.get(c)) for c in self.columns) + "\n")
        if self.tb is not None:
            step = int(row.get("episode", row.get("update", 0)))
            for k, v in row.items():
                if (
                    k not in ("phase", "episode")
                    and isinstance(v, (int, float))
                    and not (isinstance(v, float) and math.isnan(v))
                ):
                    self.tb.add_scalar(k, v, step)
            self.tb.flush()

    def close(self) -> None:
        """Closes the TensorBoard writer, if any."""
        if self.tb is not None:
            self.tb.close()


def row_episode(row: dict[str, Any], key: str = "episode") -> int | None:
    """The episode (or other ``key`` counter) of a curves.csv row, or None when the row is damaged."""
    if row.get("phase") not in ("il", "rl", "ppo") or None in row or None in row.values():
        return None
    try:
        return int(row[key])
    except (TypeError, ValueError):
        return None
