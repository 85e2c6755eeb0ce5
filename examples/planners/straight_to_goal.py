#!/usr/bin/env python3
"""A planner for `socialnav evaluate --policy exec:...` that imports nothing but the standard library.

It speaks the JSON-lines format of docs/exec_protocol.md: a hello answered once, then one observation
line in and one action line out per step. The robot heads straight for its goal at its preferred speed,
slowing down on the last step so as not to pass it (as the `linear` policy does).

    socialnav evaluate --policy "exec:python examples/planners/straight_to_goal.py" --preset wang2022
"""

import json
import math
import sys


def main() -> None:
    """Answers the hello, then one action line per observation line until stdin closes."""
    hello = json.loads(sys.stdin.readline())
    if hello.get("protocol") != "socialnav-exec" or hello.get("version") != 1:
        sys.exit(f"unsupported protocol {hello.get('protocol')!r} version {hello.get('version')!r}")
    dt, kinematics = hello["dt"], hello["kinematics"]
    unicycle = kinematics in ("unicycle", "diff_drive")
    print(json.dumps({"protocol": "socialnav-exec", "version": 1, "format": "json",
                      "name": "straight_to_goal.py"}), flush=True)
    for line in sys.stdin:
        frame = json.loads(line)
        actions = []
        for robot in frame["robot"]:  # px, py, vx, vy, radius, gx, gy, v_pref, theta
            dx, dy = robot[5] - robot[0], robot[6] - robot[1]
            d = math.hypot(dx, dy)
            speed = min(robot[7], d / dt)
            if unicycle:  # (v, d theta): turn towards the goal as far as one step allows, then drive
                turn = math.remainder(math.atan2(dy, dx) - robot[8], 2 * math.pi)
                if kinematics == "diff_drive":  # only the speed along the heading (the world's limits apply)
                    speed = max(speed * math.cos(turn), 0.0)
                actions.append([speed, turn])
            else:
                actions.append([speed * dx / d, speed * dy / d] if d > 1e-9 else [0.0, 0.0])
        print(json.dumps({"actions": actions}), flush=True)


if __name__ == "__main__":
    main()
