"""Surface runs at constant feed: ramps in the leads, the work at one feed, slow rows and short leads reported.

A run (lead-in, work, lead-out poses of one path segment) is one section of
``pathlaw``: a cubic spline q(s) through its poses in TCP chord length s (mm),
at rest at both ends. The feed policy sets the target speed of every piece:

- ``feed = "constant"``, ``slow_scope = "row"`` (default): the work of the run at one
  feed, the commanded one or, where the limits do not allow it anywhere on the
  row, the highest constant feed that fits the whole row; the leads no faster.
- ``feed = "constant"``, ``slow_scope = "stretch"``: the commanded feed except on the
  stretches of work that cannot run at it; each such stretch at its own highest
  constant feed. The speed changes lie outside the stretch (in the faster work next to it).
- ``feed = "max"``: every piece as fast as the limits allow up to the commanded feed
  (targets in steps of 1 % of it); speed changes wherever needed.

The ramps from and to rest lie at the run ends, i.e. in the leads when they are
long enough (``short_leads`` lists the others, with the lead length the ramp
needs). ``run_leads`` gives that length for one run (``assemble.lead_needed_mm``
for a whole joint path); ``lead_bound_mm`` a conservative bound from the joint
rates alone.

Every run is planned, sampled and checked by ``pathlaw.time_section`` (once: ``time_run_section``); the
result is the waypoint times, through-states and the samples inside pieces
(S-curves only: at constant feed the Hermite pieces between poses are exact).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CamtoolError, PlanInfeasible
from ..path.toolpath import ZONE_CODE
from .pathlaw import LeavesJointRange, PathSpline, SectionPlan, scurve, speed_bounds, time_run_section, transition_limits
from .quintic import MARGIN

FEED_POLICIES = ("constant", "max")
SLOW_SCOPES = ("row", "stretch")
MAX_POLICY_STEP = 0.01      # "max": targets in steps of this share of the commanded feed
SLOW_REPORT_RATIO = 0.995   # work plateaus below this share of the commanded feed are reported
MIN_PIECE_S = 1e-3          # a piece without TCP motion gets at least its joint time (>= this)
WORK, LEAD_IN, LEAD_OUT = ZONE_CODE["work"], ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]


@dataclass(frozen=True)
class RunsTiming:
    """All runs of a joint path timed at once, indexed by surface waypoint (as ``quintic.TimedRuns``).

    ``h_s`` (n-1,) piece durations (undefined across run ends); ``qd``, ``qdd`` (n, dof)
    through-states; inner samples (``inner_waypoint``: piece start waypoint, ``inner_t_s``
    from the piece start, states); ``slow``: one dict per slowed work stretch (surface
    waypoint range, feed, binding joint and limit); ``short_leads``: one dict per ramp
    that does not fit its lead; ``run_feed_mm_s`` (R,) the work feed of every run (its
    lowest work plateau).
    """

    h_s: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    inner_waypoint: np.ndarray
    inner_t_s: np.ndarray
    inner_q: np.ndarray
    inner_qd: np.ndarray
    inner_qdd: np.ndarray
    slow: tuple
    short_leads: tuple
    run_feed_mm_s: np.ndarray


def path_parameter(q: np.ndarray, step_mm: np.ndarray, limits, feed_mm_s: float) -> np.ndarray:
    """Knots s (mm) of a run: TCP chord lengths, at least the joint time of a piece times the feed."""
    dq = np.abs(np.diff(q, axis=0))
    h_floor = np.maximum((dq / (MARGIN * limits.velocity)).max(axis=1, initial=0.0), MIN_PIECE_S)
    return np.concatenate([[0.0], np.cumsum(np.maximum(step_mm, feed_mm_s * h_floor))])


def targets(bound: np.ndarray, zone: np.ndarray, feed_mm_s: float, policy: str, scope: str) -> np.ndarray:
    """Target speed of every piece of a run for the feed policy (see the module doc).

    ``bound`` (n-1,): highest constant speed per piece; ``zone`` (n,) of the poses.
    """
    work = (zone[:-1] == WORK) & (zone[1:] == WORK)
    tgt = np.minimum(bound, feed_mm_s)
    if policy == "max":
        step = MAX_POLICY_STEP * feed_mm_s
        return np.maximum(np.floor(tgt / step) * step, np.minimum(tgt, step))
    if not work.any():
        return tgt
    if scope == "row":
        f_row = float(tgt[work].min())
        return np.minimum(tgt, f_row)
    slow = work & (tgt < feed_mm_s)
    edges = np.flatnonzero(np.diff(np.r_[0, slow.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):
        tgt[a:b] = tgt[a:b].min()
    return tgt


def time_runs(q, step_mm, first, last, run_id, zone, limits, feed_mm_s: float, policy: str = "constant",
              scope: str = "row", feed_factor=None) -> RunsTiming:
    """Time every run (see the module doc); arrays over the surface waypoints of all runs.

    ``q`` (n, dof), ``step_mm`` (n-1,) TCP distance per piece, ``first``/``last`` run-end
    flags, ``run_id`` (n,), ``zone`` (n,) zone codes; ``feed_factor`` (n,) or None: each piece's
    speed is capped at the feed times the lower factor of its two ends (dwell-time figuring).
    """
    n, dof = q.shape
    h = np.ones(max(n - 1, 0))
    qd = np.zeros((n, dof))
    qdd = np.zeros((n, dof))
    inner = {k: [] for k in ("w", "t", "q", "qd", "qdd")}
    slow, short = [], []
    starts, ends = np.flatnonzero(first), np.flatnonzero(last)
    run_feed = np.zeros(len(starts))
    for r, (a, b) in enumerate(zip(starts, ends)):
        if b == a:
            run_feed[r] = feed_mm_s
            continue
        s = path_parameter(q[a:b + 1], step_mm[a:b], limits, feed_mm_s)
        spline = PathSpline(s, q[a:b + 1])
        bound, joint, kind = speed_bounds(*spline.piece_bounds(), limits)
        if feed_factor is not None:
            bound = np.minimum(bound, feed_mm_s * np.minimum(feed_factor[a:b], feed_factor[a + 1:b + 1]))
        z = zone[a:b + 1]
        tgt = targets(bound, z, feed_mm_s, policy, scope)
        try:
            plan, smp, _ = time_run_section(spline, tgt, limits)
        except LeavesJointRange as exc:  # the poses run along a joint's limit: the plan cannot be timed (exit 3)
            out = spline.derivatives(np.linspace(s[0], s[-1], 64 * (b - a) + 1))[0]
            beyond = np.maximum(limits.lower - out, out - limits.upper).max(axis=0)
            j = int(np.argmax(beyond))
            raise PlanInfeasible(f"timing: run of surface rows {a}..{b}: {exc} (joint {j + 1} by {beyond[j]:.3g} "
                                 "between its poses, which run along its limit)",
                                 report={"timing_failed": {"rows": [int(a), int(b)], "joint": j + 1}}) from None
        except RuntimeError as exc:
            raise CamtoolError(f"timing: run of surface rows {a}..{b}: {exc}") from None
        knot_t = smp.t_s[smp.knot >= 0]
        h[a:b] = np.diff(knot_t)
        on = smp.knot >= 0
        qd[a:b + 1] = smp.qd[on]
        qdd[a:b + 1] = smp.qdd[on]
        off = np.flatnonzero(~on)
        if len(off):
            k = np.maximum.accumulate(np.where(on, smp.knot, 0))[off]  # piece each sample lies in
            inner["w"].append(a + k)
            inner["t"].append(smp.t_s[off] - knot_t[k])
            inner["q"].append(smp.q[off])
            inner["qd"].append(smp.qd[off])
            inner["qdd"].append(smp.qdd[off])
        work_piece = (z[:-1] == WORK) & (z[1:] == WORK)
        run_feed[r] = min([p.v for p in plan.plateaus if work_piece[p.a:p.b].any()], default=feed_mm_s)
        slow += _slow_plateaus(plan, work_piece, bound, joint, kind, feed_mm_s, a, r, limits)
        short += _short_leads(plan, spline, z, a, r)
    cat = (lambda key, shape: np.concatenate(inner[key]) if inner[key] else np.zeros(shape))
    return RunsTiming(h, qd, qdd, cat("w", (0,)).astype(int), cat("t", (0,)), cat("q", (0, dof)),
                      cat("qd", (0, dof)), cat("qdd", (0, dof)), tuple(slow), tuple(short), run_feed)


def _slow_plateaus(plan: SectionPlan, work_piece, bound, joint, kind, feed, a: int, run: int, limits) -> list:
    """One dict per stretch of consecutive work plateaus below ``SLOW_REPORT_RATIO`` of the feed."""
    out = []
    for p in plan.plateaus:
        w = np.flatnonzero(work_piece[p.a:p.b]) + p.a
        if not len(w) or p.v >= SLOW_REPORT_RATIO * feed:
            continue
        k = int(w[np.argmin(bound[w])])
        lowered = p.v < 0.999 * bound[w].min()  # lowered further to fit its speed changes
        item = {"run": run, "first_waypoint": a + int(w[0]), "last_waypoint": a + int(w[-1]) + 1,
                "feed_mm_s": float(p.v), "speed_ratio": float(p.v / feed), "joint": int(joint[k]),
                "limit": "ramps" if lowered else ("speed", "acceleration", "jerk")[int(kind[k])],
                "at_run_end": bool(w[0] == 0 or w[-1] == len(work_piece) - 1)}
        if out and out[-1]["last_waypoint"] == item["first_waypoint"] and out[-1]["run"] == run:
            prev = out[-1]
            if item["feed_mm_s"] < prev["feed_mm_s"]:
                prev.update(feed_mm_s=item["feed_mm_s"], speed_ratio=item["speed_ratio"], joint=item["joint"],
                            limit=item["limit"])
            prev["last_waypoint"] = item["last_waypoint"]
            prev["at_run_end"] = prev["at_run_end"] or item["at_run_end"]
        else:
            out.append(item)
    return out


def _short_leads(plan: SectionPlan, spline: PathSpline, zone, a: int, run: int) -> list:
    """Ramps from / to rest that reach into the work: lead length, needed length, affected work length."""
    w = np.flatnonzero(zone == WORK)
    if not len(w) or not plan.plateaus:
        return []
    s = spline.s
    out = []
    d_in, d_out = plan.transitions[0]["D"], plan.transitions[-1]["D"]
    lead_in, lead_out = float(s[w[0]] - s[0]), float(s[-1] - s[w[-1]])
    for side, lead, need in (("lead_in", lead_in, d_in), ("lead_out", lead_out, d_out)):
        if need > lead * (1 + 1e-9) + 1e-6:
            out.append({"run": run, "side": side, "waypoint": a + (int(w[0]) if side == "lead_in" else int(w[-1])),
                        "lead_mm": lead, "needed_mm": float(need),
                        "feed_mm_s": float(plan.plateaus[0 if side == "lead_in" else -1].v)})
    return out


# ----------------------------------------------------------------------------- lead length


def lead_bound_mm(limits, feed_mm_s: float, joint_rate_per_mm, share: float = MARGIN) -> float:
    """Conservative lead length (mm) for a jerk-limited ramp from rest to ``feed_mm_s``.

    ``joint_rate_per_mm`` (dof,): the largest |dq/ds| of each joint over the lead
    (rad or mm per TCP mm), e.g. from the planned joint path, or a design value.
    Curvature of the joint path is ignored (it adds q'' v^2 and q''' v^3 terms; the
    timing's own check covers them): the ramp's TCP acceleration and jerk are the
    largest that keep every joint within ``share`` of its limits.
    """
    rate = np.abs(np.asarray(joint_rate_per_mm, float))
    zero = np.zeros_like(rate)
    A, J = transition_limits(rate, zero, zero, feed_mm_s, limits, share, dv=feed_mm_s)
    if not (A > 0 and J > 0):
        return float("inf")
    if not np.isfinite(A):
        return 0.0
    return float(scurve(0.0, feed_mm_s, A, J)[2])


def run_leads(q, step_mm, zone, limits, feed_mm_s: float, policy: str = "constant", scope: str = "row") -> dict:
    """Lead lengths (mm) of one run (``q`` its poses, ``step_mm`` TCP steps, ``zone`` zone codes) and the
    lengths its ramps from / to rest need, planned as ``time_runs`` plans them; {} without work poses or
    when the run cannot be timed."""
    w = np.flatnonzero(zone == WORK)
    if len(q) < 2 or not len(w):
        return {}
    spline = PathSpline(path_parameter(q, step_mm, limits, feed_mm_s), q)
    bound, _, _ = speed_bounds(*spline.piece_bounds(), limits)
    try:
        plan, _, _ = time_run_section(spline, targets(bound, zone, feed_mm_s, policy, scope), limits)
    except RuntimeError:  # a run the time law cannot take: time_runs says so, with its rows
        return {}
    s = spline.s
    return {"lead_in_mm": float(s[w[0]] - s[0]), "lead_out_mm": float(s[-1] - s[w[-1]]),
            "lead_in_needed_mm": float(plan.transitions[0]["D"]),
            "lead_out_needed_mm": float(plan.transitions[-1]["D"])}
