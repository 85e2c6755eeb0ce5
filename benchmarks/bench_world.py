"""Throughput of the batched world: 5 ORCA humans + an ORCA robot in circle crossing.

Measures env-steps/s (one env-step = one episode advanced by dt, robot policy included) of the
batched world, and in the same run the same workload on navground's simulator (6 ORCA agents,
all active), if navground is installed. Prints human-readable lines, then one JSON object last.

Thread scaling (issue #13): the world is also measured at 1 and 2 threads (``--scaling-threads``),
alternating, ``--scaling-repeats`` times each for ``--scaling-seconds``; the best of each is kept (other
processes only ever slow a measurement down) and ``speedup_2_threads_vs_1`` is their ratio (goal 1.9).
``--scaling-ceiling`` adds the machine's own ceiling (issue #32): as many independent 1-thread worlds as
the largest thread count, one process per CPU, against one alone (``independent_ceiling_N_vs_1``), and
the share of their summed rate that the N-thread world reaches (``fraction_of_independent_ceiling_N``).

With ``--obstacles`` (issue #28) it measures instead the same workload among 8 wall segments
(``spoke_walls``: radial walls from 1.5 to 2.5 m around the centre, in the crowd's way) against the
open world and against navground's ORCA with the same walls, all in the same run, best of
``--repeats`` alternating runs each; keys ``env_steps_per_s_obstacles``, ``ratio_vs_open_world``
(goal >= 0.5) and ``ratio_vs_navground_obstacles`` (goal >= 3); and the same walls with routed
humans (``human_routes: shortest``, issue #48) against them without routes,
``ratio_routed_vs_unrouted`` (goal >= 0.8; the two worlds stepped in alternating slices in one process,
``--repeats`` x ``--seconds`` each: ``routed_vs_unrouted``), with what building the route graphs costs
(``route_graph_ms_*``). ``--lidar BEAMS`` (issue #49) adds the walled world with a BEAMS-beam lidar on
the robot (range 10 m, the observation computed every step): ``lidar_cost`` (steps/s without it over
with it; goal <= 1.5) and ``lidar_vs_navground`` (against navground's walled world with a
``LidarStateEstimation`` of BEAMS beams on one agent; goal >= 8).

    python benchmarks/bench_world.py [--batch 4096] [--seconds 5] [--threads 0]
        [--scaling-threads 1 2] [--scaling-repeats 3] [--scaling-seconds 2] [--scaling-ceiling]
    python benchmarks/bench_world.py --obstacles [--batch 4096] [--seconds 3] [--repeats 3] [--map spokes]
        [--lidar 360]
    python benchmarks/bench_world.py --obstacles --against DIR [--repeats 3] [--seconds 3]

``--against DIR`` compares two builds of the native core: the walled and the open-floor workloads
are measured with this one and with the one in the source tree DIR (``PYTHONPATH=DIR``, e.g. a copy
of ``src/`` holding ``main``'s ``_core``), alternating, each in a fresh process; best of ``--repeats``;
keys ``ratio_vs_open_world`` of each build and ``speedup_obstacles`` / ``speedup_open_world`` (this
build's env-steps/s over the other's), and the same in CPU time per env-step (``cpu_*``, all threads),
which other processes on the machine disturb less.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import sys
import time

import numpy as np

from socialnav.maps.static_map import StaticMap
from socialnav.policies import make_policy
from socialnav.scenarios import make_scenario
from socialnav.sim.settings import SensingSettings, WorldSettings
from socialnav.sim.world import World

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import add_record_arguments, cpu_model, emit, run_record  # noqa: E402  (benchmarks/ is not a package)

CROWDNAV_ENV_STEPS_PER_S = 4134  # CrowdNav's simulator on a 2-core machine (issue #2)
LIDAR_RANGE = 10.0  # [m], --lidar: both simulators' lidar


def spoke_walls() -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """8 wall segments, radial from 1.5 to 2.5 m at angles 22.5 + 45 k degrees: between the circle
    (humans start beyond ~3.3 m) and the centre, where the crowd crosses."""
    walls = []
    for k in range(8):
        a = math.pi / 8 + k * math.pi / 4
        walls.append(((1.5 * math.cos(a), 1.5 * math.sin(a)), (2.5 * math.cos(a), 2.5 * math.sin(a))))
    return walls


def room_walls() -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """8 wall segments: the 12 m x 12 m room around the circle (4 walls) and 4 short walls 1 m long
    at 2 m from the centre, tangential: fewer walls within each agent's query range than spokes."""
    walls = [((-6.0, -6.0), (6.0, -6.0)), ((6.0, -6.0), (6.0, 6.0)), ((6.0, 6.0), (-6.0, 6.0)),
             ((-6.0, 6.0), (-6.0, -6.0))]
    for k in range(4):
        a = math.pi / 4 + k * math.pi / 2
        c, t = 2.0 * np.array([math.cos(a), math.sin(a)]), 0.5 * np.array([-math.sin(a), math.cos(a)])
        walls.append((tuple(c - t), tuple(c + t)))
    return walls


MAPS = {"spokes": spoke_walls, "room": room_walls}


def warmed_up_world(batch: int, threads: int, static_map: StaticMap | None, routes: bool = False,
                    lidar: int = 0) -> tuple:
    """The benchmark's world, its ORCA robot and its observation after 50 warm-up steps."""
    sensing = SensingSettings(lidar_beams=lidar, lidar_range=LIDAR_RANGE)
    settings = WorldSettings(time_limit=25.0, threads=threads, human_routes="shortest" if routes else "none",
                             sensing=sensing)
    world = World(settings, make_scenario("circle_crossing", n_humans=5), batch, split="train", record=False,
                  static_map=static_map)
    policy = make_policy("orca", safety_space=0.0, threads=threads)
    obs = world.reset()
    for _ in range(50):  # warm-up: pages in memory, starts the worker threads
        obs = world.step(policy.act(obs), observe=True).observation
    return world, policy, obs


def measure_socialnav(batch: int, seconds: float, threads: int, static_map: StaticMap | None = None,
                      lidar: int = 0) -> dict:
    world, policy, obs = warmed_up_world(batch, threads, static_map, lidar=lidar)
    rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    env_steps, calls = 0, 0
    start, cpu_start = time.perf_counter(), time.process_time()
    while time.perf_counter() - start < seconds:
        env_steps += int(obs.active.sum())
        # observe=True: the refill and the next observation in one native pass (docs/simulator.md).
        obs = world.step(policy.act(obs), observe=True).observation
        calls += 1
    elapsed, cpu = time.perf_counter() - start, time.process_time() - cpu_start
    rss_after = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    state_arrays = [
        world.position,
        world.velocity,
        world.goal,
        world.radius,
        world.v_pref,
        world.mask,
        world.theta,
        world.steps,
        world.status,
        world.reward,
        world.dmin,
        world.done,
        world.overlaps,
        world.arrival,
        world.end_step,
    ]
    state_bytes = sum(a.nbytes for a in state_arrays) / batch
    world.close()
    return {
        "env_steps_per_s": env_steps / elapsed,
        # CPU time of all threads: less sensitive than env-steps/s to other processes on the machine.
        "cpu_us_per_env_step": 1e6 * cpu / env_steps,
        "agent_steps_per_s": 6 * env_steps / elapsed,
        "batch_calls_per_s": calls / elapsed,
        "state_bytes_per_episode": state_bytes,
        "peak_rss_growth_mb": (rss_after - rss_before) / 1024,
        "threads": WorldSettings(threads=threads).resolved_threads,
    }


def routed_vs_unrouted(batch: int, seconds: float, threads: int, static_map: StaticMap,
                       slice_steps: int = 10) -> dict:
    """The walled world with routed humans against the same world without routes, interleaved in one
    process: slices of ``slice_steps`` steps of each in turn, ``seconds`` of each in all. Other processes and
    a virtual machine's changing speed slow both alike, so the ratio of their rates varies far less from
    run to run than that of two measurements taken one after the other (on a 2-core virtual machine
    those spread from 0.69 to 0.83 for one build; interleaved, within about 0.03 for runs minutes apart,
    though runs hours apart still spread from 0.76 to 0.84)."""
    # per world: the world, its policy, its observation, env-steps and seconds so far
    worlds = {routed: [*warmed_up_world(batch, threads, static_map, routed), 0, 0.0]
              for routed in (False, True)}
    while min(w[4] for w in worlds.values()) < seconds:
        for state in worlds.values():
            world, policy, obs = state[0], state[1], state[2]
            steps, start = 0, time.perf_counter()
            for _ in range(slice_steps):
                steps += int(obs.active.sum())
                obs = world.step(policy.act(obs), observe=True).observation
            state[2], state[3], state[4] = obs, state[3] + steps, state[4] + time.perf_counter() - start
    for state in worlds.values():
        state[0].close()
    rate = {routed: state[3] / state[4] for routed, state in worlds.items()}
    return {"env_steps_per_s_routed": rate[True], "env_steps_per_s_unrouted_interleaved": rate[False],
            "ratio_routed_vs_unrouted": rate[True] / rate[False]}


def state_digest(batch: int, threads: int, steps: int = 300) -> str:
    """SHA-256 of the world's state after ``steps`` steps of a fixed-seed run (auto-reset included)."""
    import hashlib

    settings = WorldSettings(time_limit=25.0, threads=threads)
    world = World(settings, make_scenario("circle_crossing", n_humans=5), batch, split="train", record=False)
    policy = make_policy("orca", safety_space=0.0, threads=threads)
    obs = world.reset()
    for _ in range(steps):
        obs = world.step(policy.act(obs), observe=True).observation
    h = hashlib.sha256()
    for arr in (world.position, world.velocity, world.goal, world.steps, world.status, world.reward):
        h.update(np.ascontiguousarray(arr).tobytes())
    world.close()
    return h.hexdigest()




def _measure_one_command(workload: str, batch: int, seconds: float, threads: int, map_name: str) -> list[str]:
    """This script's command that prints measure_socialnav of one workload (``obstacles`` or ``open``)."""
    return [sys.executable, os.path.abspath(__file__), "--measure-one", workload, "--map", map_name,
            "--batch", str(batch), "--seconds", str(seconds), "--threads", str(threads)]


def _measured(stdout: str) -> dict:
    """The measurement that a ``--measure-one`` process printed as its last line."""
    return json.loads(stdout.strip().splitlines()[-1])


def _measure_in_process(pythonpath: str, workload: str, args: argparse.Namespace) -> dict:
    """measure_socialnav of one workload (``obstacles`` or ``open``) with the core on ``pythonpath``."""
    import subprocess

    command = _measure_one_command(workload, args.batch, args.seconds, args.threads, args.map)
    out = subprocess.run(command, env=dict(os.environ, PYTHONPATH=os.path.abspath(pythonpath)), check=True,
                         capture_output=True, text=True).stdout
    return _measured(out)


def independent_worlds(cpus: list[int], batch: int, seconds: float) -> list[float]:
    """env-steps/s of one 1-thread world of ``batch`` episodes per CPU in ``cpus``, all at the same time.

    Each world runs in a process of its own pinned to its CPU: no thread pool, nothing shared. Their
    sum against one such world alone is the machine's own ceiling for the thread scaling (its cores'
    speed under load, shared caches and memory), which no threading of one world can pass.
    """
    import subprocess

    command = _measure_one_command("open", batch, seconds, 1, "spokes")  # the map is unused on the open floor
    pin = getattr(os, "sched_setaffinity", None)  # Linux; elsewhere the processes are not pinned
    procs = [
        subprocess.Popen(command, stdout=subprocess.PIPE, text=True,
                         preexec_fn=(lambda c=c: pin(0, {c})) if pin else None)
        for c in cpus
    ]
    outs = [p.communicate()[0] for p in procs]
    if any(p.returncode for p in procs):
        raise RuntimeError(f"an independent world failed (exit codes {[p.returncode for p in procs]})")
    return [_measured(out)["env_steps_per_s"] for out in outs]


def usable_cpus() -> list[int]:
    """The CPUs this process may run on (a container may allow fewer than the machine has)."""
    affinity = getattr(os, "sched_getaffinity", None)
    return sorted(affinity(0)) if affinity else list(range(os.cpu_count() or 1))


def scaling_ceiling(best: dict[int, float], batch: int, seconds: float) -> dict:
    """The ``--scaling-ceiling`` keys: the largest thread count against as many independent worlds."""
    cpus = usable_cpus()
    n = min(max(best), len(cpus))
    # The lone world on the second CPU: the first also takes the interrupts.
    alone = independent_worlds([cpus[1 % n]], batch, seconds)[0]
    together = sum(independent_worlds(cpus[:n], batch, seconds))
    keys = {
        "independent_worlds": n,
        "independent_alone_env_steps_per_s": round(alone),
        "independent_together_env_steps_per_s": round(together),
        f"independent_ceiling_{n}_vs_1": together / alone,
    }
    if n in best:
        keys[f"fraction_of_independent_ceiling_{n}"] = best[n] / together
    print(f"ceiling: {n} independent 1-thread worlds (B={batch} each) {together:,.0f} env-steps/s, "
          f"{together / alone:.2f}x one alone ({alone:,.0f})"
          + (f"; {n} threads reach {best[n] / together:.2f} of it" if n in best else ""))
    return keys


def main_against(args: argparse.Namespace) -> None:
    """The --obstacles --against benchmark: two builds, walled and open floor, alternating."""
    import socialnav

    ours = os.path.dirname(os.path.dirname(os.path.abspath(socialnav.__file__)))
    builds = {"this": ours, "other": args.against}
    best = {(b, w): 0.0 for b in builds for w in ("obstacles", "open")}
    best_cpu = {(b, w): math.inf for b in builds for w in ("obstacles", "open")}
    for _ in range(args.repeats):
        for workload in ("obstacles", "open"):
            for build, path in builds.items():
                run = _measure_in_process(path, workload, args)
                best[build, workload] = max(best[build, workload], run["env_steps_per_s"])
                best_cpu[build, workload] = min(best_cpu[build, workload], run["cpu_us_per_env_step"])
    result = {"batch": args.batch, "cpu_count": os.cpu_count(), "cpu_model": cpu_model(), "map": args.map,
              "repeats": args.repeats, "other_build": os.path.abspath(args.against)}
    for build in builds:
        result[f"env_steps_per_s_obstacles_{build}"] = best[build, "obstacles"]
        result[f"env_steps_per_s_open_world_{build}"] = best[build, "open"]
        result[f"ratio_vs_open_world_{build}"] = best[build, "obstacles"] / best[build, "open"]
        result[f"cpu_us_per_env_step_obstacles_{build}"] = best_cpu[build, "obstacles"]
        result[f"cpu_us_per_env_step_open_world_{build}"] = best_cpu[build, "open"]
        result[f"cpu_ratio_vs_open_world_{build}"] = best_cpu[build, "open"] / best_cpu[build, "obstacles"]
        print(f"{build} build: {best[build, 'obstacles']:,.0f} env-steps/s with walls, "
              f"{best[build, 'open']:,.0f} open -> ratio {result[f'ratio_vs_open_world_{build}']:.3f}")
    result["speedup_obstacles"] = best["this", "obstacles"] / best["other", "obstacles"]
    result["speedup_open_world"] = best["this", "open"] / best["other", "open"]
    result["cpu_speedup_obstacles"] = best_cpu["other", "obstacles"] / best_cpu["this", "obstacles"]
    result["cpu_speedup_open_world"] = best_cpu["other", "open"] / best_cpu["this", "open"]
    print(f"this build / other: {result['speedup_obstacles']:.3f}x with walls, "
          f"{result['speedup_open_world']:.3f}x on the open floor (env-steps/s); in CPU time per env-step "
          f"{result['cpu_speedup_obstacles']:.3f}x and {result['cpu_speedup_open_world']:.3f}x")
    result["load_average_1min"] = os.getloadavg()[0]
    rounded = {k: round(v, 3) if isinstance(v, float) else v for k, v in result.items()}
    print(json.dumps(run_record() | rounded))


def route_graph_cost(static_map: StaticMap, pillar_maps: int = 200) -> dict:
    """What building the route graphs costs (issue #48): the benchmark's map, and the maps that
    circle_crossing_obstacles draws per episode (each distinct map gets its own graphs, cached), both
    inflations of a 0.3 m human with the default 0.2 m clearance, timed from an empty cache."""
    from socialnav import _core
    from socialnav.maps.routes import plan_route

    def build(m: StaticMap) -> float:
        _core.clear_route_cache()
        start = time.perf_counter()
        plan_route(m, (-10.0, -10.0), (10.0, 10.0), radius=0.3)  # builds the graphs of both inflations
        return time.perf_counter() - start

    bench_ms = 1e3 * min(build(static_map) for _ in range(5))
    with World(WorldSettings(), make_scenario("circle_crossing_obstacles"), pillar_maps, count=pillar_maps,
               record=False) as world:
        world.reset()
        maps = [m for m in world.static_maps if m is not None]
    total = sum(build(m) for m in maps)
    _core.clear_route_cache()
    per_map = 1e3 * total / max(len(maps), 1)
    return {"route_graph_ms_bench_map": bench_ms, "route_graph_ms_per_pillar_map": per_map,
            "pillar_maps": len(maps)}


def main_obstacles(args: argparse.Namespace) -> None:
    """The --obstacles benchmark: walls vs open floor vs navground with walls, alternating."""
    walls = MAPS[args.map]()
    static_map = StaticMap(tuple(np.array(w) for w in walls))
    sys.path.insert(0, os.path.dirname(__file__))
    from _navground_workload import navground_env_steps_per_s

    best = {"obstacles": 0.0, "open": 0.0, "navground_obstacles": 0.0, "navground_open": 0.0,
            "lidar": 0.0, "navground_lidar": 0.0}
    threads = None
    for _ in range(args.repeats):
        if args.lidar:
            with_lidar = measure_socialnav(args.batch, args.seconds, args.threads, static_map,
                                           lidar=args.lidar)
            best["lidar"] = max(best["lidar"], with_lidar["env_steps_per_s"])
            ng_lidar = navground_env_steps_per_s(seconds=args.seconds, walls=walls, lidar=args.lidar,
                                                 lidar_range=LIDAR_RANGE)
            best["navground_lidar"] = max(best["navground_lidar"], ng_lidar["env_steps_per_s"])
        walled = measure_socialnav(args.batch, args.seconds, args.threads, static_map)
        threads = walled["threads"]
        best["obstacles"] = max(best["obstacles"], walled["env_steps_per_s"])
        open_floor = measure_socialnav(args.batch, args.seconds, args.threads)
        best["open"] = max(best["open"], open_floor["env_steps_per_s"])
        ng = navground_env_steps_per_s(seconds=args.seconds, walls=walls)
        best["navground_obstacles"] = max(best["navground_obstacles"], ng["env_steps_per_s"])
        ng_open = navground_env_steps_per_s(seconds=args.seconds)
        best["navground_open"] = max(best["navground_open"], ng_open["env_steps_per_s"])
    result = {
        "batch": args.batch,
        "cpu_count": os.cpu_count(),
        "cpu_model": cpu_model(),
        "threads": threads,
        "walls": len(walls),
        "map": args.map,
        "repeats": args.repeats,
        "env_steps_per_s_obstacles": best["obstacles"],
        "env_steps_per_s_open_world": best["open"],
        "navground_env_steps_per_s_obstacles": best["navground_obstacles"],
        "ratio_vs_open_world": best["obstacles"] / best["open"],
        "ratio_vs_navground_obstacles": best["obstacles"] / best["navground_obstacles"],
        "navground_env_steps_per_s_open_world": best["navground_open"],
        "navground_ratio_obstacles_vs_open": best["navground_obstacles"] / best["navground_open"],
        **routed_vs_unrouted(args.batch, args.seconds * args.repeats, args.threads, static_map),
        **route_graph_cost(static_map),
    }
    if args.lidar:
        result |= {
            "lidar_beams": args.lidar,
            "lidar_range_m": LIDAR_RANGE,
            "env_steps_per_s_lidar": best["lidar"],
            "navground_env_steps_per_s_lidar": best["navground_lidar"],
            "lidar_vs_navground": best["lidar"] / best["navground_lidar"],
            "lidar_cost": best["obstacles"] / best["lidar"],
            "navground_lidar_cost": best["navground_obstacles"] / best["navground_lidar"],
        }
    result["meets_target"] = bool(
        result["ratio_vs_open_world"] >= 0.5 and result["ratio_vs_navground_obstacles"] >= 3
        and result["ratio_routed_vs_unrouted"] >= 0.8
        and (not args.lidar or (result["lidar_vs_navground"] >= 8 and result["lidar_cost"] <= 1.5))
    )
    result["load_average_1min"] = os.getloadavg()[0]
    print(f"socialnav with {len(walls)} walls: {best['obstacles']:,.0f} env-steps/s "
          f"(B={args.batch}, {threads} threads)")
    print(f"socialnav open floor: {best['open']:,.0f} env-steps/s -> ratio "
          f"{result['ratio_vs_open_world']:.2f} (goal 0.5)")
    print(f"navground with the same walls: {best['navground_obstacles']:,.0f} env-steps/s -> ratio "
          f"{result['ratio_vs_navground_obstacles']:.1f}x (goal 3)")
    print(f"socialnav with the walls and routed humans: {result['env_steps_per_s_routed']:,.0f} env-steps/s "
          f"-> ratio {result['ratio_routed_vs_unrouted']:.2f} to the same walls without routes, interleaved "
          f"(goal 0.8)")
    print(f"route graphs: {result['route_graph_ms_bench_map']:.2f} ms for this map (both inflations), "
          f"{result['route_graph_ms_per_pillar_map']:.2f} ms per circle_crossing_obstacles map (mean of "
          f"{result['pillar_maps']})")
    if args.lidar:
        print(f"socialnav with the walls and a {args.lidar}-beam lidar: {best['lidar']:,.0f} env-steps/s "
              f"-> lidar_cost {result['lidar_cost']:.2f} (goal <= 1.5); navground with its lidar: "
              f"{best['navground_lidar']:,.0f} env-steps/s (its cost {result['navground_lidar_cost']:.2f}) "
              f"-> lidar_vs_navground {result['lidar_vs_navground']:.1f}x (goal 8)")
    rounded = {k: round(v, 3) if isinstance(v, float) else v for k, v in result.items()}
    emit(run_record() | rounded, args)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--batch", type=int, default=4096)
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--threads", type=int, default=0)
    parser.add_argument("--scaling-threads", type=int, nargs="*", default=[1, 2])
    parser.add_argument("--scaling-repeats", type=int, default=3)
    parser.add_argument("--scaling-seconds", type=float, default=2.0)
    parser.add_argument("--scaling-ceiling", action="store_true",
                        help="also run as many independent 1-thread worlds as the largest --scaling-threads, "
                        "one process per CPU, for the machine's own ceiling (issue #32)")
    parser.add_argument("--obstacles", action="store_true", help="the walls benchmark (issue #28)")
    parser.add_argument("--repeats", type=int, default=3, help="--obstacles: alternating runs, best kept")
    parser.add_argument("--map", choices=sorted(MAPS), default="spokes",
                        help="--obstacles: the 8 walls (spokes: radial, in the crowd's way; room: the room's "
                        "4 walls and 4 short ones)")
    parser.add_argument("--lidar", type=int, default=0, metavar="BEAMS",
                        help="--obstacles: also the walled world with a BEAMS-beam lidar on the robot, "
                        "against it without and against navground's LidarStateEstimation (issue #49)")
    parser.add_argument("--against", metavar="DIR",
                        help="--obstacles: also measure the core in source tree DIR (A/B of two builds)")
    parser.add_argument("--measure-one", choices=["obstacles", "open"], help=argparse.SUPPRESS)
    add_record_arguments(parser, "bench_world")
    args = parser.parse_args()
    if args.measure_one:  # one measurement for --against, in a process of its own
        walls = MAPS[args.map]() if args.measure_one == "obstacles" else None
        static_map = StaticMap(tuple(np.array(w) for w in walls)) if walls else None
        print(json.dumps(measure_socialnav(args.batch, args.seconds, args.threads, static_map)))
        return
    if args.obstacles and args.against:
        main_against(args)
        return
    if args.obstacles:
        main_obstacles(args)
        return

    ours = measure_socialnav(args.batch, args.seconds, args.threads)
    print(
        f"socialnav: {ours['env_steps_per_s']:,.0f} env-steps/s (B={args.batch}, {ours['threads']} threads, "
        f"{os.cpu_count()} cores)"
    )
    result = {"batch": args.batch, "cpu_count": os.cpu_count(), **ours}
    if args.scaling_threads:
        best = {t: 0.0 for t in args.scaling_threads}
        for _ in range(args.scaling_repeats):
            for t in args.scaling_threads:
                best[t] = max(
                    best[t], measure_socialnav(args.batch, args.scaling_seconds, t)["env_steps_per_s"]
                )
        result["env_steps_per_s_by_threads"] = {str(t): round(v) for t, v in best.items()}
        line = ", ".join(f"{t} threads {v:,.0f}" for t, v in best.items())
        if 1 in best and 2 in best:
            result["speedup_2_threads_vs_1"] = best[2] / best[1]
            line += f"; 2 vs 1 threads: {best[2] / best[1]:.2f}x (goal 1.9x)"
        for t in best:
            if t > 2 and 1 in best:
                result[f"speedup_{t}_threads_vs_1"] = best[t] / best[1]
                line += f"; {t} vs 1 threads: {best[t] / best[1]:.2f}x"
        print(f"scaling (best of {args.scaling_repeats}): {line}")
        digests = {t: state_digest(args.batch, t) for t in args.scaling_threads}
        result["bit_identical_across_threads"] = len(set(digests.values())) == 1
        print(f"bit-identical final state for threads {sorted(digests)}: "
              f"{result['bit_identical_across_threads']}")
        if args.scaling_ceiling:
            result |= scaling_ceiling(best, args.batch, args.scaling_seconds)
    try:
        sys.path.insert(0, os.path.dirname(__file__))
        from _navground_workload import navground_env_steps_per_s

        ng = navground_env_steps_per_s(seconds=args.seconds)
        result["navground_env_steps_per_s"] = ng["env_steps_per_s"]
        result["ratio_vs_navground"] = ours["env_steps_per_s"] / ng["env_steps_per_s"]
        print(
            f"navground: {ng['env_steps_per_s']:,.0f} env-steps/s (6 ORCA agents) -> ratio "
            f"{result['ratio_vs_navground']:.1f}x"
        )
    except ImportError as err:
        print(f"navground not measured: {err}")
        result["navground_env_steps_per_s"] = None
        result["ratio_vs_navground"] = None
    result["ratio_vs_crowdnav"] = ours["env_steps_per_s"] / CROWDNAV_ENV_STEPS_PER_S
    result["target_env_steps_per_s"] = 100 * CROWDNAV_ENV_STEPS_PER_S
    result["meets_target"] = bool(
        ours["env_steps_per_s"] >= 100 * CROWDNAV_ENV_STEPS_PER_S
        and (result["ratio_vs_navground"] or 0) >= 2.0
    )
    result["load_average_1min"] = os.getloadavg()[0]
    rounded = {k: round(v, 3) if isinstance(v, float) else v for k, v in result.items()}
    emit(run_record() | rounded, args)


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
