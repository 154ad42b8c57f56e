"""TCP feed of a timed trajectory: TCP distance over time on its resampling, statistics and a plot.

The feed is measured on what a controller runs: the trajectory resampled every
``dt`` (``sampled.SampledMotion``), TCP positions by forward kinematics, and the
feed of each sample interval = TCP distance / time. A sample interval counts
as *work* when it lies between two consecutive ``work`` waypoints (the same
rule as ``work_time_s``). Shares are shares of work **length**.

``tcp_positions_world(robot, q)`` is vectorised for DH robots (the TCP carried
through the DH transforms, one batch of products per joint, checked against
Pinocchio on first use) and falls back to Pinocchio in a loop for other robots.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..path.toolpath import ZONE_CODE
from .. import safe_io

FEED_TOLERANCES = (0.01, 0.02)   # shares of the commanded feed reported (within +-1 %, +-2 %)
FK_BLOCK = 50000                 # configurations per vectorised FK batch (bounded temporaries)


# ----------------------------------------------------------------------------- forward kinematics


def _dh_tail(robot) -> tuple[np.ndarray, bool, np.ndarray]:
    """(DH table (n, 5), modified?, constant transform after the DH chain incl. the tool)."""
    dh = np.array([[r.a_mm, r.alpha_rad, r.d_mm, r.theta_rad, float(r.prismatic)] for r in robot.dh])
    modified = robot.convention == "modified"
    zero = np.zeros((1, robot.dof))
    chain = _dh_chain(dh, modified, zero)[0]
    tail = np.linalg.solve(chain, robot.fk(zero[0])) @ robot.tool_T_mm
    return dh, modified, tail


def _dh_chain(dh: np.ndarray, modified: bool, q: np.ndarray) -> np.ndarray:
    """(m, 4, 4) product of the DH transforms at configurations q (m, n)."""
    m = len(q)
    T = np.broadcast_to(np.eye(4), (m, 4, 4)).copy()
    for i, (a, al, d, th, pr) in enumerate(dh):
        dd = d + (q[:, i] if pr > 0.5 else 0.0)
        tt = th + (0.0 if pr > 0.5 else q[:, i])
        dd = np.broadcast_to(dd, (m,))
        tt = np.broadcast_to(tt, (m,))
        ct, st, ca, sa = np.cos(tt), np.sin(tt), np.cos(al), np.sin(al)
        A = np.zeros((m, 4, 4))
        A[:, 3, 3] = 1.0
        if modified:
            A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, a
            A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st * ca, ct * ca, -sa, -sa * dd
            A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = st * sa, ct * sa, ca, ca * dd
        else:
            A[:, 0, 0], A[:, 0, 1], A[:, 0, 2], A[:, 0, 3] = ct, -st * ca, st * sa, a * ct
            A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st, ct * ca, -ct * sa, a * st
            A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = sa, ca, dd
        T = T @ A
    return T


def _dh_point(dh: np.ndarray, modified: bool, q: np.ndarray, point: np.ndarray) -> np.ndarray:
    """(m, 3) ``point`` (3,), given in the last DH frame, in the chain's base frame at configurations q (m, n):
    the DH transforms applied to the point from the last joint back, three coordinates at a time (a
    quarter of the products of ``_dh_chain``'s 4 x 4 matrices, which the feed does not need)."""
    m = len(q)
    x, y, z = (np.full(m, float(c)) for c in point)
    for i in range(len(dh) - 1, -1, -1):
        a, al, d, th, pr = dh[i]
        dd = d + (q[:, i] if pr > 0.5 else 0.0)
        tt = th + (0.0 if pr > 0.5 else q[:, i])
        ct, st, ca, sa = np.cos(tt), np.sin(tt), np.cos(al), np.sin(al)
        if modified:   # RotX(alpha) TransX(a) RotZ(theta) TransZ(d)
            u = ct * x - st * y
            w = st * x + ct * y
            x, y, z = u + a, ca * w - sa * (z + dd), sa * w + ca * (z + dd)
        else:          # RotZ(theta) TransZ(d) TransX(a) RotX(alpha)
            u = x + a
            w = ca * y - sa * z
            x, y, z = ct * u - st * w, st * u + ct * w, sa * y + ca * z + dd
    return np.column_stack([x, y, z])


_DH_CACHE: dict = {}


def tcp_positions_world(robot, q: np.ndarray) -> np.ndarray:
    """World-frame TCP positions (m, 3) in mm for configurations ``q`` (m, dof): ``base_T_mm @ fk_tcp(q)``."""
    q = np.asarray(q, float).reshape(-1, robot.dof)
    out = np.empty((len(q), 3))
    base = np.asarray(robot.base_T_mm, float)
    if not getattr(robot, "dh", ()):
        for k, x in enumerate(q):
            out[k] = (base @ robot.fk_tcp(x))[:3, 3]
        return out
    key = (id(robot), robot.name)
    if key not in _DH_CACHE or _DH_CACHE[key][0] is not robot:
        dh, modified, tail = _dh_tail(robot)
        rng = np.random.default_rng(0)
        L = robot.limits
        probe = L.lower + (L.upper - L.lower) * rng.random((4, robot.dof))
        mine = _dh_point(dh, modified, probe, tail[:3, 3])
        if not all(np.allclose(mine[k], robot.fk_tcp(probe[k])[:3, 3], atol=1e-6) for k in range(len(probe))):
            raise RuntimeError(f"vectorised kinematics of {robot.name} disagree with Pinocchio")
        _DH_CACHE.clear()
        _DH_CACHE[key] = (robot, dh, modified, tail)
    _, dh, modified, tail = _DH_CACHE[key]
    for a in range(0, len(q), FK_BLOCK):
        tcp = _dh_point(dh, modified, q[a:a + FK_BLOCK], tail[:3, 3])
        out[a:a + FK_BLOCK] = tcp @ base[:3, :3].T + base[:3, 3]
    return out


# ----------------------------------------------------------------------------- feed profile


@dataclass(frozen=True)
class FeedProfile:
    """Feed per sample interval of a resampled trajectory.

    ``s_mm`` (K,) TCP path length at each sample, ``feed_mm_s`` (K-1,) feed of each
    interval (nan for an empty interval), ``length_mm`` (K-1,), ``work`` (K-1,)
    bool, ``run`` (K-1,) number of the work stretch (consecutive work intervals;
    -1 outside work) and ``t_s`` (K,) sample times.
    """

    t_s: np.ndarray
    s_mm: np.ndarray
    feed_mm_s: np.ndarray
    length_mm: np.ndarray
    work: np.ndarray
    run: np.ndarray


def feed_profile(trajectory, sampled) -> FeedProfile:
    """TCP feed of ``trajectory`` on its resampling ``sampled`` (``sampled.SampledMotion``: times, TCP)."""
    t = np.asarray(sampled.t_s, float)
    p = np.asarray(sampled.tcp_mm, float)
    dl = np.linalg.norm(np.diff(p, axis=0), axis=1)
    dt = np.diff(t)
    with np.errstate(invalid="ignore", divide="ignore"):
        feed = np.where(dt > 0, dl / np.where(dt > 0, dt, 1.0), np.nan)
    tw = np.asarray(trajectory.t_s, float)
    zone = np.asarray(trajectory.zone)
    wk = ZONE_CODE["work"]
    both = np.zeros(len(tw), bool)  # waypoint interval k (k, k+1) is work
    both[:-1] = (zone[:-1] == wk) & (zone[1:] == wk)
    mid = 0.5 * (t[:-1] + t[1:])
    k = np.clip(np.searchsorted(tw, mid, side="right") - 1, 0, max(len(tw) - 2, 0))
    work = both[k] & (dt > 0)
    # a new work stretch wherever the work interval chain is broken (a non-work waypoint interval between)
    start = work & ~np.r_[False, work[:-1]]
    run = np.where(work, np.cumsum(start) - 1, -1)
    s = np.concatenate([[0.0], np.cumsum(dl)])
    return FeedProfile(t, s, feed, dl, work, run)


def feed_statistics(profile: FeedProfile, feed_mm_s: float) -> dict:
    """Shares of work length within +-1 % and +-2 % of ``feed_mm_s``, min / median / max work feed."""
    w = profile.work & np.isfinite(profile.feed_mm_s)
    length = profile.length_mm[w]
    v = profile.feed_mm_s[w]
    total = float(length.sum())
    out = {"commanded_feed_mm_s": float(feed_mm_s), "work_length_mm": total}
    for tol in FEED_TOLERANCES:
        ok = np.abs(v - feed_mm_s) <= tol * feed_mm_s
        out[f"work_share_within_{round(100 * tol)}pct"] = float(length[ok].sum() / total) if total > 0 else 0.0
    if len(v):
        order = np.argsort(v)
        cum = np.cumsum(length[order])
        median = float(v[order][np.searchsorted(cum, 0.5 * cum[-1])]) if cum[-1] > 0 else float(np.median(v))
        out.update(min_work_feed_mm_s=float(v.min()), median_work_feed_mm_s=median,
                   max_work_feed_mm_s=float(v.max()))
    else:
        out.update(min_work_feed_mm_s=0.0, median_work_feed_mm_s=0.0, max_work_feed_mm_s=0.0)
    return out


PLOT_BINS = 3000  # feed PNG: more intervals than this are drawn as the min and max of this many bins


def display_envelope(x: np.ndarray, v: np.ndarray, bins: int = PLOT_BINS) -> tuple[np.ndarray, np.ndarray]:
    """(x, v) for display: as given up to ``2 * bins`` points, else per bin of consecutive intervals its
    lowest and highest feed at the bin's middle (slowdowns and spikes stay visible; NaN where a bin
    has none, so gaps stay gaps)."""
    if len(v) <= 2 * bins:
        return x, v
    edges = np.linspace(0, len(v), bins + 1).astype(int)
    lo = np.fmin.reduceat(v, edges[:-1])
    hi = np.fmax.reduceat(v, edges[:-1])
    mid = 0.5 * (x[edges[:-1]] + x[edges[1:] - 1])
    return np.repeat(mid, 2), np.column_stack([lo, hi]).ravel()


def plot_feed(profile: FeedProfile, feed_mm_s: float, png_path, title: str = "") -> "Path":
    """PNG of TCP feed against TCP path length; work intervals highlighted, commanded feed dashed
    (long profiles drawn as a min / max envelope, ``display_envelope``)."""
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    png_path = Path(png_path)
    png_path.parent.mkdir(parents=True, exist_ok=True)
    x = 0.5 * (profile.s_mm[:-1] + profile.s_mm[1:]) / 1000.0
    v = profile.feed_mm_s
    vw = np.where(profile.work, v, np.nan)
    top = np.nanmax(v) if np.isfinite(v).any() else feed_mm_s
    x_all, v_all = display_envelope(x, v)
    x_work, v_work = display_envelope(x, vw)
    fig, ax = plt.subplots(figsize=(12, 4), dpi=110)
    ax.plot(x_all, v_all, color="#bbbbbb", lw=0.6, label="all zones")
    ax.plot(x_work, v_work, color="#1f77b4", lw=1.0, label="work")
    ax.axhline(feed_mm_s, color="#d62728", ls="--", lw=0.8, label=f"commanded {feed_mm_s:g} mm/s")
    for tol in FEED_TOLERANCES:
        ax.axhspan(feed_mm_s * (1 - tol), feed_mm_s * (1 + tol), color="#2ca02c", alpha=0.08)
    ax.set_xlabel("TCP path length [m]")
    ax.set_ylabel("TCP feed [mm/s]")
    ax.set_ylim(0, max(1.2 * feed_mm_s, min(float(top) * 1.05, 3 * feed_mm_s)))
    if title:
        ax.set_title(title)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    safe_io.save_figure(fig, png_path)
    plt.close(fig)
    return png_path
