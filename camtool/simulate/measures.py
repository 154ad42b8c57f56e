"""What the simulator measures: distances of the simulated TCP from the planned path, and the
report (``SimReport``) with its summary lines."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .reference import REF_SAG_MM, Reference

def _distance_to_polyline(X: np.ndarray, ref: Reference, t: np.ndarray | None = None,
                          exact_above: float = 0.0) -> np.ndarray:
    """Distance (mm) of points X from the reference: the nearer of its polyline and, when it
    has one, the planned motion's curve (``Reference.motion``).

    With the points' times ``t`` (s from the program's start) and the reference's times, each
    point is first measured against the five segments around the one the plan is on at that
    time (exact while the program keeps the plan's clock, an upper bound always); only points
    farther than ``exact_above`` (the tolerance) are searched over the whole reference."""
    d = _distance_to_lines(X, ref, t, exact_above)
    if ref.motion is not None and len(ref.motion.points):
        far = np.flatnonzero(d > max(REF_SAG_MM, 0.5 * exact_above))
        if len(far):
            d[far] = np.minimum(d[far], _distance_to_lines(X[far], ref.motion, None if t is None else t[far],
                                                           exact_above))
    return d


def _segments(X, V, brk, starts):
    """Distance of X from the segments starting at ``starts`` (clipped; across a break, from
    the start point alone)."""
    a = np.clip(starts, 0, len(V) - 2)
    va = V[a]
    d = V[a + 1] - va
    w = X - va
    dd = np.einsum("ki,ki->k", d, d)
    s = np.einsum("ki,ki->k", w, d) / np.where(dd > 0, dd, 1.0)
    np.clip(s, 0.0, 1.0, out=s)
    s[brk[a]] = 0.0
    w -= s[:, None] * d
    return np.sqrt(np.einsum("ki,ki->k", w, w))


def _distance_to_lines(X: np.ndarray, ref: Reference, t=None, exact_above: float = 0.0) -> np.ndarray:
    """Distance (mm) of points X from a polyline: from the vertices the plan is at about the
    points' times (when known), else from each point's two nearest vertices, the segments on
    either side of them."""
    V = ref.points
    if len(V) == 0 or len(X) == 0:
        return np.full(len(X), np.nan)
    if len(V) == 1:
        return np.linalg.norm(X - V[0], axis=1)
    best = np.full(len(X), np.inf)
    todo = np.arange(len(X))
    if t is not None and ref.times is not None and len(ref.times) == len(V):
        i = np.searchsorted(ref.times, t)
        # the program keeps the plan's clock: the plan is near here (``window`` segments either side)
        for off in range(-ref.window - 1, ref.window + 1):
            best = np.minimum(best, _segments(X, V, ref.breaks, i + off))
        todo = np.flatnonzero(best > exact_above)
    if len(todo):
        Xt = X[todo]
        dist, nn = ref.tree().query(Xt, k=2)
        b = np.min(dist, axis=1)
        for j in range(2):
            for off in (-1, 0):
                b = np.minimum(b, _segments(Xt, V, ref.breaks, nn[:, j] + off))
        best[todo] = np.minimum(best[todo], b)
    return best


# --- the simulation -----------------------------------------------------------------------------

SPEED_REL_TOL = 1e-3       # joint speeds may exceed the limit by 0.1 % (written resolution)
TIME_REL_TOL = 0.005       # program time within 0.5 % of the plan
DEV_ABS_TOL_MM = 1e-3      # the written resolution of positions


def limit_findings(prog, robot, chain, s) -> tuple[int, int, list[str]]:
    """(samples outside the position limits, samples above the speed limits, findings)."""
    findings: list[str] = []
    t, q, m, M, S = s.t, s.q, s.m, len(prog), len(s.t)
    # --- limits
    Lm = robot.limits
    tol = np.where(chain.prismatic, 5e-4, np.radians(5e-5)) + 1e-9
    over = (q < Lm.lower - tol) | (q > Lm.upper + tol)
    n_lim = int(over.any(axis=1).sum())
    if n_lim:
        k0 = int(np.flatnonzero(over.any(axis=1))[0])
        i0 = int(np.flatnonzero(over[k0])[0])
        findings.append(f"{prog.where[m[k0]] if M > 1 else prog.where[0]}: {robot.joint_names[i0]} leaves its limits "
                        f"at t = {t[k0]:.3f} s ({n_lim} samples)")
    n_speed = 0
    if S > 1:
        n_speed, first = _speed_excess(q, t, Lm.velocity * (1 + SPEED_REL_TOL), 2 * tol)
        if n_speed:
            k0, i0, v0 = first
            unit = "mm/s" if chain.prismatic[i0] else "deg/s"
            conv = (lambda x: x) if chain.prismatic[i0] else np.degrees
            findings.append(f"{prog.where[m[k0 + 1]]}: {robot.joint_names[i0]} moves at "
                            f"{conv(v0):.2f} {unit}, above its limit "
                            f"{conv(Lm.velocity[i0]):.2f} {unit} ({n_speed} samples)")
    return n_lim, n_speed, findings


BLOCK_SAMPLES = 20_000  # samples measured at a time: a block's (samples x dof) temporaries stay a
                       # few MB, not the hundreds of MB of a whole program's samples


def _blocks(n: int):
    """Slices covering range(n) in blocks of ``BLOCK_SAMPLES``."""
    return [slice(a, min(a + BLOCK_SAMPLES, n)) for a in range(0, n, BLOCK_SAMPLES)]


def unfollowed_moves(robot, chain, s) -> tuple:
    """(start, end) times (s) of the moves where the simulated joints leave their limits, exceed their
    speed or found no solution (``Samples.unsolved``), in order: what the post stage writes again
    as joint moves (``camtool.program.post``)."""
    t, q, m = s.t, s.q, s.m
    Lm = robot.limits
    tol = np.where(chain.prismatic, 5e-4, np.radians(5e-5)) + 1e-9
    bad = ((q < Lm.lower - tol) | (q > Lm.upper + tol)).any(axis=1)
    if len(t) > 1:
        dts = np.diff(t)
        good = dts > 1e-9
        v = np.abs(np.diff(q, axis=0)) / np.where(good, dts, 1.0)[:, None]
        fast = good & (v > Lm.velocity * (1 + SPEED_REL_TOL) + 2 * tol / np.where(good, dts, 1.0)[:, None]).any(axis=1)
        bad[:-1] |= fast   # a step belongs to the move its first sample is in
    bad[np.asarray(s.unsolved, int)] = True
    moves = np.unique(m[bad])
    moves = moves[moves > 0]
    return tuple((float(s.T[k - 1]), float(s.T[k])) for k in moves)


def _speed_excess(q, t, speed, slack) -> tuple[int, tuple | None]:
    """(sample steps whose joint speed |dq| / dt exceeds ``speed`` + ``slack`` / dt, the first one as
    (step, joint, speed) or None), block by block over the steps of ``q`` (S, dof) at times ``t``."""
    count, first = 0, None
    for b in _blocks(len(t) - 1):
        nxt = slice(b.start + 1, b.stop + 1)
        dts = t[nxt] - t[b]
        good = dts > 1e-9
        v = np.abs(q[nxt] - q[b])[good] / dts[good, None]
        sp = v > speed[None, :] + slack[None, :] / dts[good, None]
        rows = np.flatnonzero(sp.any(axis=1))
        count += len(rows)
        if first is None and len(rows):
            i0 = int(np.flatnonzero(sp[rows[0]])[0])
            first = (b.start + int(np.flatnonzero(good)[rows[0]]), i0, float(v[rows[0], i0]))
    return count, first


@dataclass(frozen=True)
class Surface:
    """Where the program says the process runs: rows (first, last move), the samples on work,
    moves on work, exact stops and part switches on the surface, every part switch."""

    rows: list
    on_work: np.ndarray
    moves_on_work: int
    stops_surface: int
    switches_surface: int
    switch_after: np.ndarray
    blend_zero: np.ndarray


def surface_of(prog, s) -> tuple[Surface, list[str]]:
    """The rows from the program's markers and what happens on them (exact stops, switches)."""
    findings: list[str] = []
    t, T, M, S = s.t, s.T, len(prog), len(s.t)
    # --- the surface: rows from the program's markers
    starts = np.flatnonzero(prog.row_start)
    ends = np.flatnonzero(prog.row_end)
    rows = []
    e_i = 0
    for a in starts:
        e = ends[ends >= a]
        if not len(e):
            findings.append(f"{prog.where[a]}: a row starts and never ends")
            break
        rows.append((int(a), int(e[0])))
    on_work = np.zeros(S, bool)
    moves_on_work = 0
    stops_surface = 0
    switches_surface = 0
    part = np.asarray(prog.part)
    switch_after = np.r_[part[1:] != part[:-1], False]
    blend_zero = np.asarray(prog.blend_mm) <= 0
    for a, b in rows:
        lo, hi = np.searchsorted(t, [T[a], T[b]], side="left")
        on_work[lo:hi + 1] = True
        moves_on_work += b - a
        st = np.flatnonzero(blend_zero[a:b + 1]) + a
        st = st[(st > 0) & (st < M - 1)]  # the first move comes from anywhere; the last ends the program
        if a == b:  # a row of one point is a touch (seed 002's targets): the process stops there
            st = st[:0]
        for k in st:
            stops_surface += 1
            if stops_surface <= 10:
                findings.append(f"{prog.where[k]}: exact stop on the surface")
        sw = np.flatnonzero(switch_after[a:b + 1]) + a
        for k in sw:
            switches_surface += 1
            if switches_surface <= 10:
                findings.append(f"{prog.where[k]}: the program switches module / job on the surface")
    del e_i
    return Surface(rows, on_work, moves_on_work, stops_surface, switches_surface, switch_after, blend_zero), findings


def work_figures(prog, chain, s, surf: Surface, reference: Reference | None, path_tol_mm: float | None):
    """(work length mm, feed statistics, max and p99 deviation mm, planned duration, findings, each move's
    deviation (``move_deviations``)) of the samples on work, against the planned path."""
    findings: list[str] = []
    t, q, m, M, S, total = s.t, s.q, s.m, len(prog), len(s.t), s.total
    on_work, rows = surf.on_work, surf.rows
    # --- feed and deviation on work
    work_len = 0.0
    feed = {}
    X = np.full((S, 3), np.nan)
    work_at = np.flatnonzero(on_work)
    for b in _blocks(len(work_at)):  # the TCP is measured where it is on the surface
        X[work_at[b]] = chain.fk(q[work_at[b]])[0]
    if S > 1 and on_work.any():
        seg = on_work[1:] & on_work[:-1]
        d = np.where(seg, np.linalg.norm(np.diff(X, axis=0), axis=1), 0.0)
        dts = np.diff(t)
        work_len = float(d[seg].sum())
        vv = d[seg & (dts > 1e-9)] / dts[seg & (dts > 1e-9)]
        if len(vv):
            feed = {"mean_mm_s": float(work_len / max(dts[seg].sum(), 1e-12)), "min_mm_s": float(vv.min()),
                    "max_mm_s": float(vv.max()), "p1_mm_s": float(np.percentile(vv, 1)),
                    "p99_mm_s": float(np.percentile(vv, 99))}
            target = reference.feed_mm_s if reference is not None else None
            if target:
                w = dts[seg & (dts > 1e-9)]
                rel = np.abs(vv / target - 1)
                feed.update(commanded_mm_s=float(target),
                            within_1pct=float(w[rel <= 0.01].sum() / w.sum()),
                            within_2pct=float(w[rel <= 0.02].sum() / w.sum()))
    max_dev = p99 = None
    planned = None
    moves_dev: tuple = ()
    if reference is not None:
        planned = reference.duration_s
        if on_work.any():
            tol = path_tol_mm if path_tol_mm is not None else 0.0
            dev = np.concatenate([_distance_to_polyline(X[work_at[b]], reference, t[work_at[b]], tol)
                                  for b in _blocks(len(work_at))])   # each point's distance is its own
            max_dev, p99 = float(np.max(dev)), float(np.percentile(dev, 99))
            moves_dev = move_deviations(s, work_at, dev)
            if path_tol_mm is not None and max_dev > path_tol_mm + DEV_ABS_TOL_MM:
                worst = int(np.flatnonzero(on_work)[int(np.argmax(dev))])
                findings.append(f"{prog.where[m[worst]] if M > 1 else prog.where[0]}: the simulated TCP is "
                                f"{max_dev:.3f} mm from the planned path (tolerance {path_tol_mm:g} mm) at "
                                f"t = {t[worst]:.3f} s")
        if reference.rows is not None and reference.rows != len(rows):
            findings.append(f"{prog.where[0].rsplit(':', 1)[0]}: the program has {len(rows)} rows, the plan "
                            f"{reference.rows}")
        if planned and abs(total - planned) > TIME_REL_TOL * planned:
            findings.append(f"{prog.where[0].rsplit(':', 1)[0]}: the program takes {total:.3f} s, the plan "
                            f"{planned:.3f} s ({100 * (total / planned - 1):+.2f} %, allowed "
                            f"{100 * TIME_REL_TOL:.1f} %)")
    return work_len, feed, max_dev, p99, planned, findings, moves_dev


def move_deviations(s, work_at: np.ndarray, dev: np.ndarray) -> tuple:
    """(start, end, deviation) of every move with samples on work, in order: its time span (s) and the
    largest distance (mm) of those samples from the planned path; where the post stage writes the
    program closer to the plan (``camtool.program.post``)."""
    if not len(work_at):
        return ()
    worst = np.full(len(s.T), -1.0)
    np.maximum.at(worst, s.m[work_at], dev)
    return tuple((float(s.T[k - 1]) if k > 0 else 0.0, float(s.T[k]), float(worst[k]))
                 for k in np.flatnonzero(worst >= 0))


@dataclass
class SimReport:
    """What a program does when the controller runs it (see module doc)."""

    moves: int
    duration_s: float
    planned_duration_s: float | None
    rows: int
    work_length_mm: float
    work_time_s: float
    moves_on_work: int
    max_deviation_mm: float | None
    p99_deviation_mm: float | None
    feed: dict
    exact_stops: int
    exact_stops_on_surface: int
    part_switches: int
    part_switches_on_surface: int
    limit_violations: int
    speed_violations: int
    samples: int
    findings: list = field(default_factory=list)
    cell: dict | None = None      # the cell pass on the simulated motion (a world given): pairs, evaluations
    unfollowed_s: tuple = ()      # (start, end) s of each move the controller cannot follow as written (no
                                  # joint solution, a joint above its speed or outside its limits); not reported
    deviation_s: tuple = ()       # (start s, end s, deviation mm) of each move on work (``move_deviations``);
                                  # not reported

    def as_dict(self) -> dict:
        from dataclasses import asdict
        out = asdict(self)
        out.pop("unfollowed_s")
        out.pop("deviation_s")
        return out


def summary_lines(rep: SimReport) -> list[str]:
    """A few human lines about a simulation."""
    out = [f"simulated {rep.moves} moves, {rep.duration_s:.3f} s"
           + (f" (plan {rep.planned_duration_s:.3f} s)" if rep.planned_duration_s else "")
           + f", {rep.samples} samples"]
    out.append(f"work: {rep.rows} rows, {rep.work_length_mm / 1000:.3f} m, {rep.moves_on_work} moves "
               f"({rep.moves_on_work / max(rep.work_length_mm / 1000, 1e-9):.1f} per m)")
    if rep.max_deviation_mm is not None:
        out.append(f"deviation from the planned path on work: max {rep.max_deviation_mm:.4f} mm, "
                   f"p99 {rep.p99_deviation_mm:.4f} mm")
    if rep.feed:
        f = rep.feed
        line = f"feed on work: mean {f['mean_mm_s']:.2f}, p1 {f['p1_mm_s']:.2f}, p99 {f['p99_mm_s']:.2f} mm/s"
        if "within_1pct" in f:
            line += f"; {100 * f['within_1pct']:.1f} % within 1 %, {100 * f['within_2pct']:.1f} % within 2 %"
        out.append(line)
    out.append(f"exact stops: {rep.exact_stops} ({rep.exact_stops_on_surface} on the surface); module/job "
               f"switches: {rep.part_switches} ({rep.part_switches_on_surface} on the surface); limit "
               f"violations: {rep.limit_violations} position, {rep.speed_violations} speed samples")
    return out
