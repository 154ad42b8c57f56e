"""The assembly of a timed trajectory, pinned against a plain re-computation; read-only arrays; samples reused."""
import ast
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import camtool.trajectory as trajectory_module
from camtool.settings import TimingSettings
from camtool.timing import (SampledMotion, check_trajectory, limit_findings, sample_trajectory, sampled_for,
                            tcp_positions_world, time_trajectory,
                            timing_report)
from camtool.timing.assemble import _stretched
from camtool.timing.sampled import sample_motion
from camtool.timing.flow import corner_poses, flow_chain, hard_steps
from camtool.timing.quintic import MARGIN
from camtool.timing.ruckig_moves import RuckigMover, rest_to_rest_chain
from camtool.timing.ruckig_through import TIME_GRID_S, through_pieces
from camtool.timing.runs import time_runs
from camtool.path.toolpath import ZONE_CODE, ZONES
from camtool.trajectory import Trajectory
from test_timing_fixtures import joint_path_and_path, retract_path, seed8, transition_path, two_runs

ROBOT = seed8()
SURFACE = [ZONE_CODE[z] for z in ("work", "lead_in", "lead_out")]


def _with_leads(n=120, lead=5):
    """two_runs with the first and last ``lead`` poses of each run as lead-in and lead-out."""
    jp, _ = two_runs(ROBOT, n=n)
    zone = np.array(jp.zone)
    for a in (0, n + 2):
        zone[a:a + lead], zone[a + n - lead:a + n] = ZONE_CODE["lead_in"], ZONE_CODE["lead_out"]
    return joint_path_and_path(ROBOT, jp.q, zone, np.array([0] * (n + 1) + [1] * (n + 1)))


CASES = {"two_runs": two_runs(ROBOT), "transition": transition_path(ROBOT), "retract": retract_path(ROBOT)[:2],
         "leads": _with_leads()}


def reference(jp, path, robot, method, zones, tcp_speed_mm_s, feed="constant", scope="row"):
    """The timed waypoints and slow-downs, re-computed from the building blocks in one plain loop.

    Runs (surface rows of one segment) are timed together by ``runs.time_runs`` (and
    ``through_pieces``, whose fallback pieces keep the law's samples stretched to the
    time grid); the free rows between runs by the chain timing of ``zones``. Pieces
    follow one another; each after the first drops its first sample; a run with ruckig
    pieces starts on the 2^-30 s grid (the sample before it moved there).
    """
    L = robot.limits
    q, zone, pidx = np.asarray(jp.q, float), np.asarray(jp.zone), np.asarray(jp.path_index)
    n = len(q)
    surface = np.isin(zone, SURFACE)
    seg = [int(path.segment[p]) if p >= 0 else -1 for p in pidx]
    runs = []
    for i in range(n):
        if surface[i] and i > 0 and surface[i - 1] and seg[i] == seg[i - 1]:
            runs[-1].append(i)
        elif surface[i]:
            runs.append([i])
    rows = [r for run in runs for r in run]
    first = np.array([r == run[0] for run in runs for r in run])
    last = np.array([r == run[-1] for run in runs for r in run])
    tcp = np.array([path.poses_mm[p][:3, 3] if p >= 0 else (robot.base_T_mm @ robot.fk_tcp(q[r]))[:3, 3]
                    for r, p in zip(rows, pidx[rows])])
    law = time_runs(q[rows], np.linalg.norm(np.diff(tcp, axis=0), axis=1), first, last, np.cumsum(first) - 1,
                    zone[rows], L, tcp_speed_mm_s, feed, scope)
    pieces = np.flatnonzero(~last[:-1])
    h = law.h_s.copy()
    inner = {}  # surface waypoint -> [(t from piece start, q, qd, qdd)]
    ruckig = method == "ruckig" and len(pieces) > 0
    law_pieces = set(range(len(h)))
    if ruckig:
        tp = through_pieces(L, q[rows], law.qd, law.qdd, law.h_s, pieces, share=MARGIN)
        grid = np.ceil(law.h_s[pieces] / TIME_GRID_S) * TIME_GRID_S
        used = tp.used & (tp.duration_s <= grid)  # a ruckig piece that needs longer keeps the law's samples
        h[pieces] = np.where(used, tp.duration_s, grid)
        for k, t, a, b, c in zip(pieces[tp.piece], tp.t_s, tp.q, tp.qd, tp.qdd):
            if used[np.flatnonzero(pieces == k)[0]]:
                inner.setdefault(int(k), []).append((t, a, b, c))
        law_pieces = set(pieces[~used].tolist())
    sel = np.array([int(w) in law_pieces for w in law.inner_waypoint], bool)
    from camtool.timing.assemble import InnerSamples
    mine = InnerSamples(law.inner_waypoint[sel], law.inner_t_s[sel], law.inner_q[sel], law.inner_qd[sel],
                        law.inner_qdd[sel])
    if ruckig and sel.any():
        mine = _stretched(mine, law, h)
    for k, t, a, b, c in zip(mine.waypoint, mine.t_s, mine.q, mine.qd, mine.qdd):
        inner.setdefault(int(k), []).append((t, a, b, c))
    k_of = {r: k for k, r in enumerate(rows)}
    mover = RuckigMover(L)
    out = []  # [t, q, qd, qdd, zone, path_index] per sample
    offset, run_start = 0.0, {}
    prev = 0
    for run in runs + [None]:
        stop = run[0] + 1 if run else n
        if stop - prev >= 2 or (run is None and not out):
            samples = _chain_samples(jp, robot, mover, zones, list(range(prev, stop)))
            out += [[offset + t, *x] for i, (t, *x) in enumerate(samples) if i or not out]
            offset += float(samples[-1][0])
        if run is None:
            break
        if ruckig and out:
            grid = math.ceil(offset / TIME_GRID_S) * TIME_GRID_S
            if grid != offset:
                out[-1][0] = grid
                offset = grid
        ks = [k_of[r] for r in run]
        t_way = np.concatenate([[0.0], np.cumsum(h[ks[0]:ks[-1]])])
        samples = [(t_way[i], q[r], law.qd[k], law.qdd[k], zone[r], pidx[r]) for i, (r, k) in enumerate(zip(run, ks))]
        for i, k in enumerate(ks[:-1]):
            z0, z1 = zone[run[i]], zone[run[i + 1]]
            z = z0 if z0 == z1 or z1 == ZONE_CODE["work"] else z1
            samples += [(t_way[i] + t, a, b, c, z, -1) for t, a, b, c in sorted(inner.get(k, []), key=lambda x: x[0])]
        samples.sort(key=lambda x: x[0])  # stable: a waypoint before a sample at the same time
        run_start[run[0]] = offset
        out += [[offset + t, *x] for i, (t, *x) in enumerate(samples) if i or not out]
        offset += float(t_way[-1])
        prev = run[-1]
    t_s = np.array([x[0] for x in out])
    slowdowns = []
    names = robot.joint_names
    for s in law.slow:
        ka, kb = s["first_waypoint"], s["last_waypoint"]
        a, b = rows[ka], rows[kb]
        run = next(r for r in runs if a in r)
        ks = [k_of[r] for r in run]
        t_way = run_start[run[0]] + np.concatenate([[0.0], np.cumsum(h[ks[0]:ks[-1]])])
        slowdowns.append({
            "first_row": a, "last_row": b, "first_path_index": int(pidx[a]), "last_path_index": int(pidx[b]),
            "t_start_s": float(t_way[ka - ks[0]]), "t_end_s": float(t_way[kb - ks[0]]),
            "speed_ratio": float(s["speed_ratio"]), "feed_mm_s": float(s["feed_mm_s"]),
            "joint": names[int(s["joint"])], "limit": s["limit"], "run": int(s["run"]), "zone": ZONES[int(zone[a])],
            "at_run_end": bool(s["at_run_end"])})
    return {"t_s": t_s, "q": np.array([x[1] for x in out]), "qd": np.array([x[2] for x in out]),
            "qdd": np.array([x[3] for x in out]), "zone": np.array([x[4] for x in out]),
            "path_index": np.array([x[5] for x in out]), "slowdowns": tuple(slowdowns)}


def _chain_samples(jp, robot, mover, zones, chain_rows):
    """(t, q, qd, qdd, zone, path_index) of the free chain through ``chain_rows``, t from its start."""
    q, zone, pidx = np.asarray(jp.q, float), np.asarray(jp.zone), np.asarray(jp.path_index)
    surface = np.isin(zone, SURFACE)
    qs = q[chain_rows]
    if zones == "flow":
        hard = hard_steps(qs, robot.prismatic, np.asarray(jp.jump)[chain_rows],
                          (zone[chain_rows] == ZONE_CODE["retract"]) | np.asarray(jp.retract)[chain_rows])
        rest = corner_poses(qs, pidx[chain_rows] < 0, robot.limits.velocity)
        t, cq, cv, ca, pose = flow_chain(mover, qs, hard, rest)
    else:
        t, cq, cv, ca, pose = rest_to_rest_chain(mover, qs)
    result, at = [], 0
    for i in range(len(t)):
        if pose[i] >= 0:  # at a pose: its zone and Path index
            at = pose[i]
            result.append((t[i], cq[i], cv[i], ca[i], zone[chain_rows[at]], pidx[chain_rows[at]]))
        else:  # inside a step: the step's free pose's zone, self_motion between two surface poses
            r0, r1 = chain_rows[at], chain_rows[min(at + 1, len(chain_rows) - 1)]
            z = zone[r1] if not surface[r1] else zone[r0] if not surface[r0] else ZONE_CODE["self_motion"]
            result.append((t[i], cq[i], cv[i], ca[i], z, -1))
    return result


@pytest.mark.parametrize("case,method,zones,speed", [
    ("two_runs", "quintic", "stop", 100.0), ("two_runs", "ruckig", "flow", 100.0),
    ("two_runs", "quintic", "stop", 1500.0), ("two_runs", "ruckig", "stop", 1500.0),
    ("transition", "ruckig", "stop", 100.0), ("transition", "quintic", "flow", 100.0),
    ("retract", "ruckig", "flow", 100.0), ("retract", "quintic", "stop", 100.0),
    ("leads", "ruckig", "stop", 100.0), ("leads", "ruckig", "flow", 1500.0)])
def test_assembly_is_the_plain_recomputation_bit_for_bit(case, method, zones, speed):
    jp, path = CASES[case]
    tr = time_trajectory(jp, path, ROBOT, TimingSettings.make(method=method, zones=zones, tcp_speed_mm_s=speed))
    ref = reference(jp, path, ROBOT, method, zones, speed)
    for name in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(tr, name), ref[name]), name
    assert tr.slowdowns == ref["slowdowns"]
    assert tr.slowdowns or speed < 1000  # the fast cases compare real slow-downs


@pytest.mark.parametrize("feed,scope,method", [("constant", "stretch", "quintic"), ("max", "row", "ruckig")])
def test_assembly_with_the_feed_policies(feed, scope, method):
    jp, path = CASES["leads"]
    tr = time_trajectory(jp, path, ROBOT, TimingSettings.make(method=method, feed=feed, slow_scope=scope,
                                                              tcp_speed_mm_s=1500.0))
    ref = reference(jp, path, ROBOT, method, "flow", 1500.0, feed, scope)
    for name in ("t_s", "q", "qd", "qdd", "zone", "path_index"):
        assert np.array_equal(getattr(tr, name), ref[name]), name
    assert tr.slowdowns == ref["slowdowns"] and tr.slowdowns
    assert (tr.feed, tr.slow_scope) == (feed, scope)


TR = time_trajectory(*CASES["two_runs"], ROBOT, TimingSettings.make(method="ruckig", check_dt_ms=3.0))


def test_arrays_are_read_only():
    names = ("prismatic", "t_s", "q", "qd", "qdd", "zone", "path_index", "piece_row", "piece_zone", "piece_ruckig",
             "piece_reason")
    arrays = [getattr(TR, n) for n in names] + list(TR.limits.values())
    s = TR.sampled
    arrays += [s.t_s, s.tcp_mm, s.peak_ratio]
    for a in arrays:
        assert not a.flags.writeable
        with pytest.raises(ValueError):
            a[..., :1] = a[..., :1]
    assert ROBOT.prismatic.flags.writeable and ROBOT.limits.lower.flags.writeable  # the robot's stay as they were
    # a Trajectory made from views freezes copies: the viewed array stays writeable
    t = np.linspace(0.0, 1.0, 5)
    q = np.zeros((5, 8))
    tr = Trajectory("seed8", ROBOT.joint_names, ROBOT.prismatic.copy(), t[:], q[:], q[:], q[:], np.zeros(5, int),
                    np.full(5, -1), {"jerk": ROBOT.limits.jerk[:]})
    assert not tr.q.flags.writeable and q.flags.writeable and ROBOT.limits.jerk.flags.writeable


def test_sampled_motion_is_what_the_check_sampled():
    s = TR.sampled
    assert isinstance(s, SampledMotion) and s.dt_s == 0.003 and s.waypoints == len(TR.t_s)
    assert sampled_for(TR, ROBOT, 0.003) is s
    fresh = sample_trajectory(TR, 0.003)
    assert np.array_equal(fresh.t_s, s.t_s)
    assert np.array_equal(tcp_positions_world(ROBOT, fresh.q), s.tcp_mm)
    L = ROBOT.limits
    for r, (x, limit) in enumerate(((fresh.qd, L.velocity), (fresh.qdd, L.acceleration), (fresh.qddd, L.jerk))):
        assert np.array_equal(s.peak_ratio[r], (np.abs(x) / limit).max(axis=0))
    assert sampled_for(TR, ROBOT, 0.004) is not s and sampled_for(TR, ROBOT, 0.004).dt_s == 0.004
    assert check_trajectory(TR, ROBOT, samples=fresh) == [] == check_trajectory(TR, ROBOT, 0.003)
    assert limit_findings(TR, ROBOT, 0.003) == [] == limit_findings(TR, ROBOT, 0.004)
    assert timing_report(TR, ROBOT, s) == timing_report(TR, ROBOT, sample_motion(TR, ROBOT, 0.003))
    # not compared, not shown, not carried over by replace (the copy may be a different trajectory)
    assert "sampled" not in repr(TR)
    thinned = replace(TR, t_s=TR.t_s[::2], q=TR.q[::2], qd=TR.qd[::2], qdd=TR.qdd[::2], zone=TR.zone[::2],
                      path_index=TR.path_index[::2])
    assert thinned.sampled is None and not s.matches(thinned)
    assert sampled_for(thinned, ROBOT, 0.003).waypoints == len(thinned.t_s)


def test_streamed_check_finds_what_the_whole_check_finds(monkeypatch):
    """A pass in blocks says nothing; a breach in any block, the waypoints' or a late one's, gives the
    lines of the check on all samples at once."""
    monkeypatch.setattr(trajectory_module, "SAMPLE_CHUNK_WAYPOINTS", 200)
    assert len(TR.t_s) > 1000
    fast = replace(TR, t_s=TR.t_s * 0.7, qd=TR.qd / 0.7, qdd=TR.qdd / 0.49)   # every speed up by 1/0.7
    whole = check_trajectory(fast, ROBOT, samples=sample_trajectory(fast, 0.003))
    assert whole and check_trajectory(fast, ROBOT, 0.003) == whole
    k = len(TR.t_s) - 50                       # one waypoint late in the last block beyond its limit
    q = TR.q.copy()
    q[k, 3] = ROBOT.limits.upper[3] + 1e-3
    late = replace(TR, q=q)
    lines = check_trajectory(late, ROBOT, 0.003)
    assert lines == check_trajectory(late, ROBOT, samples=sample_trajectory(late, 0.003))
    assert any("position" in line for line in lines)
    seen = []
    assert check_trajectory(TR, ROBOT, 0.003, each_block=seen.append) == []
    assert len(seen) > 5 and np.array_equal(np.concatenate([b.t_s for b in seen]), sample_trajectory(TR, 0.003).t_s)


def test_samples_must_fit_the_trajectory_and_step():
    s = sample_trajectory(TR, 0.003)
    with pytest.raises(ValueError):
        check_trajectory(TR, ROBOT, 0.004, samples=s)
    other = time_trajectory(*CASES["retract"], ROBOT, TimingSettings.make())
    with pytest.raises(ValueError):
        check_trajectory(other, ROBOT, samples=s)
    with pytest.raises(ValueError):
        timing_report(other, ROBOT, TR.sampled)
    with pytest.raises(TypeError):
        timing_report(TR, ROBOT, s)
    with pytest.raises(TypeError):
        timing_report(TR, ROBOT, 0.004)
    with pytest.raises(TypeError):
        check_trajectory(TR, ROBOT)


def test_sample_trajectory_is_chunked_like_sample(monkeypatch):
    whole = sample_trajectory(TR, 0.003)
    assert len(TR.t_s) < trajectory_module.SAMPLE_CHUNK_WAYPOINTS  # one chunk: Trajectory.sample itself
    for a, b in zip((whole.t_s, whole.q, whole.qd, whole.qdd, whole.qddd),
                    TR.sample(0.003)):
        assert np.array_equal(a, b)
    monkeypatch.setattr(trajectory_module, "SAMPLE_CHUNK_WAYPOINTS", 1000)
    chunked = sample_trajectory(TR, 0.003)
    m = len(TR.t_s)
    parts = [Trajectory(TR.robot_name, TR.joint_names, TR.prismatic, TR.t_s[a:a + 1001], TR.q[a:a + 1001],
                        TR.qd[a:a + 1001], TR.qdd[a:a + 1001], TR.zone[a:a + 1001],
                        TR.path_index[a:a + 1001]).sample(0.003) for a in range(0, m - 1, 1000)]
    assert len(parts) > 5
    for i, name in enumerate(("t_s", "q", "qd", "qdd", "qddd")):
        assert np.array_equal(getattr(chunked, name), np.concatenate([p[i] for p in parts]))
    assert check_trajectory(TR, ROBOT, samples=chunked) == []


def test_checker_imports_no_timing_code():
    src = Path(trajectory_module.__file__).parent / "timing" / "check.py"
    imported = {node.module for node in ast.walk(ast.parse(src.read_text()))
                if isinstance(node, ast.ImportFrom)} | \
        {a.name for node in ast.walk(ast.parse(src.read_text())) if isinstance(node, ast.Import)
         for a in node.names}
    assert imported <= {"__future__", "typing", "numpy", "trajectory"}, imported
    assert {a.name for node in ast.walk(ast.parse(src.read_text())) if isinstance(node, ast.ImportFrom)
            and node.module == "trajectory" for a in node.names} <= {"Trajectory", "TrajectorySamples",
                                                                       "sample_blocks", "sample_trajectory"}
