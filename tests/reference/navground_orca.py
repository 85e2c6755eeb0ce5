"""RVO2/ORCA reference velocities computed by navground's ``ORCABehavior``.

navground (https://github.com/idsia-robotics/navground, tested with 0.7.0)
wraps the RVO2 library: ``ORCABehavior.desired_velocity_towards_velocity``
fills an ``RVO::Agent`` and calls RVO2's ``computeNewVelocity(time_step)``.
This module configures it to reproduce RVO2 semantics for ONE agent (agents
only, no obstacles) and returns the new velocity.

API used
--------
``navground.core.behaviors.ORCABehavior(kinematics, radius)``,
``navground.core.kinematics.OmnidirectionalKinematics(max_speed)``,
properties ``time_horizon``, ``max_number_of_neighbors``, ``horizon``,
``safety_margin``, ``social_margin.set()``, ``position``, ``velocity``,
``environment_state.neighbors = [navground.core.Neighbor(p, r, v, id)]``
(a ``GeometricState``), ``desired_velocity_towards_velocity(v_pref, dt)``
(the same call ``compute_cmd`` makes for a velocity target, minus target
scaling and kinematic clamping) and ``lines`` (the ORCA half-planes RVO2 built).

How each RVO2 parameter is mapped, and every place where navground CANNOT be
configured identically (with the work-around or bound)
-----------------------------------------------------------------------------
1. Max speed.  navground sets RVO2's ``maxSpeed_ = |v_target|`` (the norm of
   the velocity it is asked to follow), NOT the kinematics' max speed.  So
   the LP disc has radius ``|pref_velocity|``.  Identical only when
   ``|pref_velocity| == max_speed``.  Not configurable.  Work-around: we pass
   the preferred velocity unchanged and *certify* the answer with convexity:
   with ``K = H ∩ D(max_speed)`` (RVO2) and ``K' = H ∩ D(|pref|)`` (navground),
   both results are projections of ``pref`` onto a convex set, so

   * ``|pref| < max_speed`` (includes ``pref = 0``, "agent at goal"):
     navground's result ``u`` equals RVO2's if the 2-D LP was feasible (``u``
     satisfies every line in ``lines``) and either ``|u| < |pref|`` (disc
     inactive, K and K' coincide around ``u``) or ``u == pref``;
   * ``|pref| > max_speed`` ("speed-limited"): equal if ``u`` is feasible and
     ``|u| <= max_speed`` (then ``u ∈ K ⊂ K'``).

   Otherwise (disc active, or the 3-D "least penetration" fallback ran) the
   answer is *uncertified*: by default ``UncertifiedReference`` is raised,
   ``uncertified="python"`` falls back to :mod:`python_orca`, and
   ``uncertified="navground"`` returns navground's raw answer (= RVO2 with
   ``maxSpeed = |pref|``).  Note also: feeding a pre-clipped preferred
   velocity (``pref * max_speed / |pref|``) is NOT RVO2: RVO2 projects the
   unclipped ``pref`` in its LP (only its starting point is clipped).
2. Preferred velocity.  ``compute_cmd`` with ``Target.Velocity`` would take
   ``direction * get_target_speed()`` (speed clamped to the kinematics and
   replaced by ``optimal_speed`` when unset) and then clamp the result to the
   feasible twist.  We call ``desired_velocity_towards_velocity`` directly, so
   ``prefVelocity_`` is exactly the given vector and the result is RVO2's
   ``newVelocity_`` unmodified.
3. Overlap / near-contact.  navground "pushes away" every neighbour with
   ``|d| - (r + r_n + safety_margin) < 2e-3`` to a gap of exactly 2 mm
   before handing it to RVO2, so RVO2's collision branch (``1/time_step``)
   never runs and neighbours closer than 2 mm also change.  Work-around: the
   neighbour radius RVO2 uses is ``r_n + social_margin`` while the push-away
   test uses ``r_n + safety_margin + r`` without the social margin.  When any
   neighbour is within ``r + r_n + 3e-3`` we set ``social_margin = S`` (a
   power of two larger than the worst overlap) and pass ``r_n - S`` as the
   neighbour radius: the push never fires and RVO2 sees ``r_n - S + S``
   (float32 rounding <= ulp(S)/2, i.e. 1e-7 for S <= 2).  ``social_margin``
   cannot be negative (navground clamps it to 0), hence this direction.
4. Safety margin: navground adds ``safety_margin`` to the agent radius; we
   set it to 0.
5. Neighbour range.  navground uses ``rangeSq = (2 * horizon)^2``; we set
   ``horizon = neighbor_dist / 2``.  Strict ``distSq < rangeSq`` as in RVO2,
   but evaluated in float32 (neighbours within ~1e-6 m of the range boundary
   may be classified differently).
6. ``max_neighbors``: mapped to ``max_number_of_neighbors``; navground inserts
   neighbours one by one with RVO2's ``insertAgentNeighbor`` (same k-nearest
   set and order as RVO2's kd-tree; ties kept in input order).  RVO2 guards
   ``maxNeighbors_ == 0``, navground does not (undefined behaviour), so for
   ``max_neighbors <= 0`` we pass no neighbours.
7. Time step: ``desired_velocity_towards_velocity(v, dt)`` forwards ``dt`` to
   ``computeNewVelocity(dt)``: collision case uses ``1/time_step``.  Same.
8. Effective centre: only for wheeled kinematics; we use
   ``OmnidirectionalKinematics`` (holonomic) so it is off.  Same.
9. Neighbours' velocities are used as RVO2 ``velocity_`` (reciprocal ORCA,
   half of the avoidance effort).  Same.
10. Precision: this navground wheel is built with ``ng_float_t = float``
    (``navground.core.uses_doubles()`` is False) and RVO2 itself is float
    too, whereas python_orca (and presumably the C++ port under test) uses
    double.  Build-time, not configurable.  Inputs are rounded to float32 and
    all arithmetic is float32.  Measured (README.md): when RVO2's 2-D LP is
    feasible the difference to float64 is median 4e-8, max ~1e-5 m/s (the
    collision branch and line/circle near-tangencies, where a rounded
    discriminant goes through ``sqrt``, are the worst); when the 3-D
    least-penetration fallback runs, nearly parallel half-planes
    (``|det|`` just above RVO_EPSILON = 1e-5) create projected lines whose
    points lie 10-200 m away, and float32 cancellation gives errors up to
    ~2e-2 m/s.  A float32 emulation of python_orca reproduces navground's
    deviations (same magnitude, mostly identical digits), so these are
    rounding effects, not semantic differences.  ``reference_orca_details``
    reports ``infeasible=True`` for the 3-D fallback cases.
11. Obstacles are not supported (not needed; no static obstacles/lines are
    given to the state).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "UncertifiedReference",
    "navground_available",
    "max_violation",
    "raw_navground_orca",
    "reference_orca_details",
    "reference_orca_velocity",
    "compare_with_python",
]

_PUSH_EPS = 2e-3  # navground's hard-coded push-away gap [m]


class UncertifiedReference(ValueError):
    """navground cannot reproduce RVO2 for this input (see module docstring)."""


def navground_available() -> bool:
    try:
        import navground.core  # noqa: F401
    except ImportError:
        return False
    return True


def _import_navground():
    try:
        import navground.core as core
        from navground.core.behaviors import ORCABehavior
        from navground.core.kinematics import OmnidirectionalKinematics
    except ImportError as exc:  # pragma: no cover - depends on environment
        raise ImportError(
            "tests.reference.navground_orca needs navground "
            "(pip install navground==0.7.0)") from exc
    return core, ORCABehavior, OmnidirectionalKinematics


def _social_margin_workaround(position, radius, nps, nrs) -> float:
    """Smallest power of two S that keeps navground's push-away from firing."""
    if len(nrs) == 0:
        return 0.0
    dist = np.hypot(nps[:, 0] - position[0], nps[:, 1] - position[1])
    need = float(np.max(nrs + radius - dist)) + _PUSH_EPS + 1e-3
    if need <= 0.0:
        return 0.0
    return 2.0 ** math.ceil(math.log2(need))


def raw_navground_orca(position, velocity, radius, max_speed, pref_velocity,
                       neighbor_positions, neighbor_velocities, neighbor_radii,
                       time_horizon=5.0, time_step=0.25, neighbor_dist=10.0,
                       max_neighbors=10, *, push_away_workaround: bool = True):
    """navground's answer (= RVO2 with ``maxSpeed = |pref_velocity|``).

    Returns ``(new_velocity, lines)`` where ``lines`` is a list of
    ``(point, direction)`` float64 arrays (the ORCA half-planes, feasible on
    the left of ``direction``)."""
    core, ORCABehavior, OmnidirectionalKinematics = _import_navground()
    nps = np.asarray(neighbor_positions, dtype=float).reshape(-1, 2)
    nvs = np.asarray(neighbor_velocities, dtype=float).reshape(-1, 2)
    nrs = np.asarray(neighbor_radii, dtype=float).reshape(-1)
    if int(max_neighbors) <= 0:
        nps, nvs, nrs = nps[:0], nvs[:0], nrs[:0]
    position = np.asarray(position, dtype=float)

    b = ORCABehavior(kinematics=OmnidirectionalKinematics(max_speed=float(max_speed)),
                     radius=float(radius))
    b.safety_margin = 0.0
    b.time_horizon = float(time_horizon)
    b.max_number_of_neighbors = int(max(0, max_neighbors))
    b.horizon = 0.5 * float(neighbor_dist)
    b.position = position
    b.velocity = np.asarray(velocity, dtype=float)
    S = _social_margin_workaround(position, float(radius), nps, nrs) if push_away_workaround else 0.0
    b.social_margin.set(S)
    b.environment_state.neighbors = [
        core.Neighbor(nps[i], float(nrs[i]) - S, nvs[i], i) for i in range(len(nrs))]
    new_velocity = np.array(
        b.desired_velocity_towards_velocity(np.asarray(pref_velocity, dtype=float),
                                            float(time_step)), dtype=float)
    lines = [(np.array(ln.point, dtype=float), np.array(ln.direction, dtype=float))
             for ln in b.lines]
    return new_velocity, lines


def max_violation(u, lines) -> float:
    """Largest penetration of ``u`` into the ORCA half-planes ``lines``.

    > 0 (beyond float noise) means the 2-D LP was infeasible and RVO2's 3-D
    "least penetration" fallback produced ``u``."""
    worst = 0.0
    for p, d in lines:
        # RVO2: line violated iff det(direction, point - u) > 0
        worst = max(worst, d[0] * (p[1] - u[1]) - d[1] * (p[0] - u[0]))
    return worst


def reference_orca_details(position, velocity, radius, max_speed, pref_velocity,
                           neighbor_positions, neighbor_velocities, neighbor_radii,
                           time_horizon=5.0, time_step=0.25, neighbor_dist=10.0,
                           max_neighbors=10, *, speed_rtol: float = 1e-6,
                           tol: float = 1e-6) -> dict:
    """navground's answer plus whether it is certified to be RVO2's.

    Keys: ``velocity`` (navground's raw answer), ``certified`` (bool),
    ``reason`` (str), ``infeasible`` (bool: the 3-D LP fallback ran; expect
    float32 errors up to ~5e-3 m/s there, see README), ``max_violation``,
    ``lines``."""
    u, lines = raw_navground_orca(position, velocity, radius, max_speed, pref_velocity,
                                  neighbor_positions, neighbor_velocities, neighbor_radii,
                                  time_horizon, time_step, neighbor_dist, max_neighbors)
    pref = np.asarray(pref_velocity, dtype=float)
    s_pref = float(np.hypot(pref[0], pref[1]))
    m = float(max_speed)
    scale = max(1.0, m)
    viol = max_violation(u, lines)
    feasible = viol <= tol * scale
    s_u = float(np.hypot(u[0], u[1]))
    certified, reason = False, ""
    if abs(s_pref - m) <= speed_rtol * scale:
        certified, reason = True, "|pref| == max_speed"
    elif feasible and s_pref < m and float(np.hypot(*(u - pref))) <= tol * scale:
        certified, reason = True, "pref is feasible"
    elif feasible and s_pref < m and s_u < s_pref - tol * scale:
        certified, reason = True, "|pref| < max_speed, speed disc inactive"
    elif feasible and s_pref > m and s_u <= m * (1.0 + speed_rtol):
        certified, reason = True, "|pref| > max_speed, result inside max-speed disc"
    else:
        reason = (f"navground uses max speed |pref|={s_pref:.6g} instead of {m:.6g}; "
                  f"its result (|u|={s_u:.6g}, feasible={feasible}) cannot be "
                  "certified equal to RVO2's")
    return dict(velocity=u, certified=certified, reason=reason, infeasible=not feasible,
                max_violation=viol, lines=lines)


def reference_orca_velocity(position, velocity, radius, max_speed, pref_velocity,
                            neighbor_positions, neighbor_velocities, neighbor_radii,
                            time_horizon=5.0, time_step=0.25, neighbor_dist=10.0,
                            max_neighbors=10, *, uncertified: str = "raise",
                            speed_rtol: float = 1e-6, tol: float = 1e-6) -> np.ndarray:
    """New velocity (shape ``(2,)``) of RVO2's ORCA for one agent, via navground.

    Exact RVO2 semantics (up to float32 arithmetic, see the module docstring)
    whenever ``|pref_velocity| == max_speed`` (relative ``speed_rtol``); for
    other preferred speeds the answer is returned only when it is provably
    RVO2's (item 1 of the module docstring), otherwise ``uncertified`` decides:
    ``"raise"`` (:class:`UncertifiedReference`), ``"python"`` (fall back to
    :func:`tests.reference.python_orca.python_orca_velocity`) or
    ``"navground"`` (navground's answer, RVO2 with ``maxSpeed=|pref|``).
    """
    if uncertified not in ("raise", "python", "navground"):
        raise ValueError(f"uncertified must be raise|python|navground, got {uncertified!r}")
    info = reference_orca_details(position, velocity, radius, max_speed, pref_velocity,
                                  neighbor_positions, neighbor_velocities, neighbor_radii,
                                  time_horizon, time_step, neighbor_dist, max_neighbors,
                                  speed_rtol=speed_rtol, tol=tol)
    if info["certified"] or uncertified == "navground":
        return info["velocity"]
    if uncertified == "python":
        from .python_orca import python_orca_velocity
        return python_orca_velocity(position, velocity, radius, max_speed, pref_velocity,
                                    neighbor_positions, neighbor_velocities, neighbor_radii,
                                    time_horizon, time_step, neighbor_dist, max_neighbors)
    raise UncertifiedReference(info["reason"])


# ---------------------------------------------------------------------------
# Empirical comparison with the plain-Python RVO2 reference
#   python -m tests.reference.navground_orca [N] [SEED]
# ---------------------------------------------------------------------------

CLASSES = ("random", "crowded", "head_on", "speed_limited", "slow_pref",
           "at_goal", "overlap", "capped_neighbors")


def random_config(rng: np.random.Generator, kind: str) -> dict:
    """One random single-agent ORCA query of the given class."""
    radius = rng.uniform(0.3, 0.5)
    max_speed = rng.uniform(0.5, 1.5)
    position = rng.uniform(-5.0, 5.0, size=2)

    def unit(a):
        return np.array([math.cos(a), math.sin(a)])

    heading = unit(rng.uniform(-math.pi, math.pi))
    velocity = unit(rng.uniform(-math.pi, math.pi)) * rng.uniform(0.0, max_speed)
    pref_speed = max_speed
    max_neighbors = 10
    if kind == "speed_limited":
        pref_speed = max_speed * rng.uniform(1.1, 3.0)
    elif kind == "slow_pref":
        pref_speed = max_speed * rng.uniform(0.05, 0.95)
    elif kind == "at_goal":
        pref_speed = 0.0
    pref = heading * pref_speed

    if kind == "crowded":
        n = int(rng.integers(6, 13))
    elif kind == "head_on":
        n = int(rng.integers(1, 4))
    elif kind == "capped_neighbors":
        n = 12
        max_neighbors = int(rng.integers(1, 6))
    else:
        n = int(rng.integers(0, 13))
    nrs = rng.uniform(0.3, 0.5, size=n)
    nvs = np.array([unit(rng.uniform(-math.pi, math.pi)) * rng.uniform(0.5, 1.5)
                    for _ in range(n)]).reshape(n, 2)
    nps = np.zeros((n, 2))
    for i in range(n):
        if kind == "crowded":
            d = rng.uniform(radius + nrs[i] + 0.02, 3.0)
            nps[i] = position + unit(rng.uniform(-math.pi, math.pi)) * d
        elif kind == "head_on":
            along = rng.uniform(1.0, 4.0)
            lateral = rng.normal(0.0, 0.2)
            nps[i] = position + heading * along + np.array([-heading[1], heading[0]]) * lateral
            nvs[i] = -heading * rng.uniform(0.5, 1.5)
        else:
            # uniform in a 20 m box: some neighbours beyond neighbor_dist=10,
            # rejected when overlapping (the "overlap" class adds one below)
            while True:
                nps[i] = position + rng.uniform(-9.0, 9.0, size=2)
                if np.hypot(*(nps[i] - position)) > radius + nrs[i] + 0.01:
                    break
    if kind in ("overlap", "at_goal") and n == 0:
        n = 1
        nrs = rng.uniform(0.3, 0.5, size=1)
        nvs = unit(rng.uniform(-math.pi, math.pi))[None, :] * rng.uniform(0.5, 1.5)
        nps = position[None, :] + rng.uniform(1.0, 3.0) * unit(rng.uniform(-math.pi, math.pi))
    if kind == "overlap":
        k = int(rng.integers(0, n))
        nps[k] = position + unit(rng.uniform(-math.pi, math.pi)) * (
            rng.uniform(0.05, 0.99) * (radius + nrs[k]))
    return dict(position=position, velocity=velocity, radius=radius, max_speed=max_speed,
                pref_velocity=pref, neighbor_positions=nps, neighbor_velocities=nvs,
                neighbor_radii=nrs, time_horizon=5.0, time_step=0.25, neighbor_dist=10.0,
                max_neighbors=max_neighbors)


def _f32(cfg: dict) -> dict:
    """The configuration as navground sees it (inputs rounded to float32)."""
    out = {}
    for k, v in cfg.items():
        if isinstance(v, (np.ndarray, float)) and not isinstance(v, bool):
            out[k] = np.asarray(v, dtype=np.float32).astype(float)
            if np.ndim(v) == 0:
                out[k] = float(out[k])
        else:
            out[k] = v
    return out


def _sensitivity(cfg: dict, rng: np.random.Generator, trials: int = 8) -> float:
    """Change of the float64 answer under float32-sized input perturbations."""
    from .python_orca import python_orca_velocity
    base = python_orca_velocity(**cfg)
    worst = 0.0
    for _ in range(trials):
        pert = {}
        for k, v in cfg.items():
            if k in ("max_neighbors", "time_horizon", "time_step", "neighbor_dist"):
                pert[k] = v
            else:
                a = np.asarray(v, dtype=float)
                pert[k] = a * (1.0 + rng.uniform(-1, 1, size=a.shape) * 2.0 ** -24)
        worst = max(worst, float(np.max(np.abs(python_orca_velocity(**pert) - base))))
    return worst


def compare_with_python(n_configs: int = 4000, seed: int = 0, verbose: bool = True) -> dict:
    """Compare navground (as configured here) with python_orca on random queries.

    Cases are split by whether RVO2's 2-D LP is feasible (decided by the
    float64 reference) or the 3-D fallback runs ("lp3")."""
    from .python_orca import _lp2, orca_lines, python_orca_velocity
    rng = np.random.default_rng(seed)
    stats = {k: dict(n=0, certified=0, n_lp3=0, max_diff=0.0, max_diff_lp3=0.0,
                     max_diff_f32_inputs=0.0, n_over_1e6=0, raw_max_diff=0.0,
                     nopush_max_diff=0.0) for k in CLASSES}
    over = []
    for it in range(n_configs):
        kind = CLASSES[it % len(CLASSES)]
        cfg = random_config(rng, kind)
        st = stats[kind]
        st["n"] += 1
        py = python_orca_velocity(**cfg)
        lines = orca_lines(cfg["position"], cfg["velocity"], cfg["radius"],
                           cfg["neighbor_positions"], cfg["neighbor_velocities"],
                           cfg["neighbor_radii"], cfg["time_horizon"], cfg["time_step"],
                           cfg["neighbor_dist"], cfg["max_neighbors"])
        lp3 = _lp2(lines, cfg["max_speed"], tuple(cfg["pref_velocity"]), False)[0] < len(lines)
        raw, _ = raw_navground_orca(**cfg)
        st["raw_max_diff"] = max(st["raw_max_diff"], float(np.max(np.abs(raw - py))))
        nopush, _ = raw_navground_orca(**cfg, push_away_workaround=False)
        st["nopush_max_diff"] = max(st["nopush_max_diff"], float(np.max(np.abs(nopush - py))))
        try:
            ref = reference_orca_velocity(**cfg)
        except UncertifiedReference:
            continue
        st["certified"] += 1
        d = float(np.max(np.abs(ref - py)))
        if lp3:
            st["n_lp3"] += 1
            st["max_diff_lp3"] = max(st["max_diff_lp3"], d)
        else:
            st["max_diff"] = max(st["max_diff"], d)
            d32 = float(np.max(np.abs(ref - python_orca_velocity(**_f32(cfg)))))
            st["max_diff_f32_inputs"] = max(st["max_diff_f32_inputs"], d32)
        if d > 1e-6:
            st["n_over_1e6"] += 1
            over.append((d, it, kind, lp3, _sensitivity(cfg, np.random.default_rng(it))))
    over.sort(key=lambda x: -x[0])
    total = dict(n=sum(s["n"] for s in stats.values()),
                 certified=sum(s["certified"] for s in stats.values()),
                 n_lp3=sum(s["n_lp3"] for s in stats.values()),
                 max_diff=max(s["max_diff"] for s in stats.values()),
                 max_diff_lp3=max(s["max_diff_lp3"] for s in stats.values()),
                 n_over_1e6=sum(s["n_over_1e6"] for s in stats.values()))
    if verbose:
        print(f"{'class':17s} {'n':>4s} {'cert':>4s} {'lp3':>4s} {'max|d| 2D':>10s} "
              f"{'(f32 in)':>9s} {'max|d| 3D':>10s} {'>1e-6':>5s} {'raw max|d|':>10s} "
              f"{'no-push':>8s}")
        for k, s in stats.items():
            print(f"{k:17s} {s['n']:4d} {s['certified']:4d} {s['n_lp3']:4d} "
                  f"{s['max_diff']:10.3g} {s['max_diff_f32_inputs']:9.3g} "
                  f"{s['max_diff_lp3']:10.3g} {s['n_over_1e6']:5d} "
                  f"{s['raw_max_diff']:10.3g} {s['nopush_max_diff']:8.3g}")
        print("total", total)
        for d, it, kind, lp3, sens in over[:12]:
            print(f"  config {it} ({kind}, {'3-D LP' if lp3 else '2-D LP'}): |d|={d:.3g}; "
                  f"float64 answer moves by {sens:.3g} under 2^-24 input perturbations")
    return dict(classes=stats, total=total, over_1e6=over)


if __name__ == "__main__":  # pragma: no cover
    import sys
    compare_with_python(int(sys.argv[1]) if len(sys.argv) > 1 else 4000,
                        int(sys.argv[2]) if len(sys.argv) > 2 else 0)
