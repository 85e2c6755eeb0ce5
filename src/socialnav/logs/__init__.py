"""Real-world trajectories: importers (ETH/UCY, any CSV/Parquet log) and "human as robot" scoring.

    from socialnav.logs import score_file
    scores = score_file("biwi_eth.txt", format="eth-ucy", ego="all")
    scores.summaries[-1]["m1_personal_space.duration_s@eps=1.2,distance=clearance.mean"]

NumPy-only at import; ``pyarrow`` is imported when a table is read. See ``docs/real_world_logs.md``.
"""

from socialnav.logs.loading import FORMATS, DataWarning, detect_format, load_trajectories
from socialnav.logs.readers import DEFAULT_RADIUS, ETH_UCY_FPS, FIELDS, MAX_SPEED, read_eth_ucy, read_table
from socialnav.logs.scene import Scene, SceneError, scene_from_tracks
from socialnav.logs.scoring import LogScores, outcome_problems, score_file, score_trajectories

__all__ = [
    "DEFAULT_RADIUS",
    "ETH_UCY_FPS",
    "FIELDS",
    "FORMATS",
    "MAX_SPEED",
    "DataWarning",
    "LogScores",
    "Scene",
    "SceneError",
    "detect_format",
    "example_log",
    "load_trajectories",
    "outcome_problems",
    "read_eth_ucy",
    "read_table",
    "scene_from_tracks",
    "score_file",
    "score_trajectories",
]


def example_log() -> str:
    """Path of the small ETH/UCY-format example shipped with the package (``frame id x y``)."""
    from importlib.resources import files

    return str(files("socialnav.logs") / "data" / "example_eth_ucy.txt")
