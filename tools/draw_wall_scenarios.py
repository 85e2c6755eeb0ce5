"""Draw the first test episode of every scenario with walls (docs/walls_scenarios.png).

The picture shows the initial state: walls, the robot (yellow) with its goal (black star), each human
with an arrow from its start to its goal. Run from the repository root:

    PYTHONPATH=src python tools/draw_wall_scenarios.py [--out docs/walls_scenarios.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

from socialnav._io import atomic_write
from socialnav.scenarios import make_scenario
from socialnav.scenarios.francis import FRANCIS_SCENARIOS
from socialnav.viz.draw import ROBOT_EDGE, ROBOT_FACE, agent_colour, draw_static_map, new_figure


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/walls_scenarios.png")
    parser.add_argument("--index", type=int, default=0, help="test episode index to draw")
    args = parser.parse_args()
    from matplotlib.patches import Circle

    fig = new_figure((1350, 1350))
    for n, name in enumerate(FRANCIS_SCENARIOS):
        ax = fig.add_subplot(3, 3, n + 1)
        batch = make_scenario(name).episodes("test", [args.index])
        draw_static_map(ax, batch.static_map(0))
        ax.add_patch(Circle(tuple(batch.robot_start[0]), batch.robot_radius[0], facecolor=ROBOT_FACE,
                            edgecolor=ROBOT_EDGE, lw=1.5))
        ax.plot(*batch.robot_goal[0], "*", color=ROBOT_EDGE, ms=12)
        for j in range(batch.max_humans):
            colour = agent_colour(j + 1)
            start, goal = batch.human_start[0, j], batch.human_goal[0, j]
            ax.add_patch(Circle(tuple(start), batch.human_radius[0, j], color=colour, alpha=0.9))
            ax.plot(*goal, "*", color=colour, ms=8)
            if (start != goal).any():
                ax.annotate("", tuple(goal), tuple(start),
                            arrowprops={"arrowstyle": "->", "color": colour, "alpha": 0.5})
        ax.set_xlim(-6, 6)
        ax.set_ylim(-6, 6)
        ax.set_aspect("equal")
        ax.grid(alpha=0.25)
        ax.set_title(name, fontsize=10)
    fig.tight_layout()
    out = Path(args.out)
    atomic_write(out, lambda tmp: fig.savefig(tmp, format="png"))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
