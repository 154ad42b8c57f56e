"""The smallest move of the workpiece that makes every pose reachable: for a run that failed for reach.

``nearest_feasible_shift(job, settings, robot, path)`` searches translations
of the workpiece on shells of growing radius (``step_mm`` apart, 98
directions each: the 26 of a cube's faces, edges and corners and 72 spread by
a Fibonacci lattice), cheapest test first (``screen.screen_batch``: the
wrist-centre bound on every pose, then closed-form IK on a subsample), and
confirms the first placement that passes with closed-form IK on every pose.
The radius is then bisected along that direction. A placement counts when
every pose is reachable and the screen leaves a small margin
(``reach_margin`` of the arm's reach and ``joint_margin`` of each joint's
range), so that the planner, which must also keep the path continuous, does
not fail at the very edge. If no translation up to ``max_mm`` works, yaws
about world z through the workpiece origin (``yaws_deg``, nearest first) are
tried, alone and with translations.

It imports nothing of the pipeline (``camtool.run.stages``), so a task can call
it; the path is the one the failed run planned (world frame).
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .kinematics import screen_model
from .screen import PathGeometry, ScreenSettings, screen_batch

YAWS_DEG = (5.0, -5.0, 10.0, -10.0, 20.0, -20.0, 30.0, -30.0, 45.0, -45.0, 90.0, -90.0, 180.0)


def directions(n_extra: int = 72) -> np.ndarray:
    """Unit directions: the 26 of a cube (faces first, then edges, then corners) and ``n_extra`` Fibonacci ones."""
    cube = [np.array(v, float) for v in
            [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) != (0, 0, 0)]]
    cube.sort(key=lambda v: (np.count_nonzero(v), tuple(-v)))
    k = np.arange(n_extra) + 0.5
    z = 1.0 - 2.0 * k / n_extra
    phi = np.pi * (1.0 + 5 ** 0.5) * k
    fib = np.column_stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])
    d = np.vstack([np.array(cube), fib])
    return d / np.linalg.norm(d, axis=1)[:, None]


SHIFT_BUDGET = 3000      # screens a search may spend: an offset's subsample screen counts 1, a full screen 10
FULL_SCREEN_COST = 10


@dataclass(frozen=True)
class ShiftSearch:
    """How far and how hard the search looks: the screens it may spend (``budget``, counted so that the answer
    does not depend on the machine's speed or load), the largest shift and the shells' spacing (mm), the margins
    a placement must leave (shares of the arm's reach and of each joint's range), the yaws tried (deg, nearest
    first)."""

    budget: int = SHIFT_BUDGET
    max_mm: float = 600.0
    step_mm: float = 25.0
    reach_margin: float = 0.02
    joint_margin: float = 0.02
    yaws_deg: tuple[float, ...] = YAWS_DEG


def nearest_feasible_shift(job, settings, robot, path, search: ShiftSearch = ShiftSearch()) -> dict | None:
    """The smallest translation (then yaw) of the workpiece that the screen finds reachable (module doc).

    ``job`` gives the workpiece placement (the yaw pivot), ``settings`` the job's
    ``JobSettings`` (or None), ``path`` the world-frame path at that placement.
    Returns None when the robot has no closed-form families or nothing is
    found within ``search.max_mm`` and the work ``search.budget`` (screens, counted, so that the answer
    does not depend on the machine's speed or load); else a dict::

        {"dx_mm", "dy_mm", "dz_mm", "dyaw_deg", "distance_mm",
         "workpiece_xyz_mm", "workpiece_rpy_deg",     # the new cell.workpiece_* values
         "reach_used_pct", "joint_margin_pct",          # the screen's figures there
         "poses_checked", "already_reachable", "seconds", "message"}

    ``already_reachable`` is True when the screen finds every pose reachable
    at the job's own placement (then the planner failed for another reason and
    the shift, if any, only adds margin).
    """
    t0 = time.perf_counter()
    model = screen_model(robot, settings, path.free_spin)
    if model is None or len(path) == 0:
        return None
    st = ScreenSettings(feed_stencils=0)   # reach and margins only: the feed does not decide a shift
    if settings is not None:
        st = ScreenSettings(orientation_mm=settings.planner.orientation_weight_mm,
                            track_scale_mm=settings.planner.track_scale_mm, feed_stencils=0)
    pivot = np.asarray(job.cell.workpiece_xyz_mm, float)
    screens = _Screens(model, PathGeometry.build(path, model, robot, pivot, st), st, search)
    here = screens([(0.0, 0.0, 0.0, 0.0)])[0]
    already = bool(here.feasible)
    if screens.good(here):
        f = screens.confirm([here])
        if f is not None:
            return _answer(job, f, 0.0, already, len(path), t0)
    found = _first_on_shells(screens, search)
    if found is None:
        return None
    f = _bisected(screens, *found, search.step_mm)
    dist = float(np.linalg.norm(f.offset[:3]))
    return _answer(job, f, dist, already, len(path), t0)


class _Screens:
    """The screens of one search, counted against its budget: an offset's subsample screen counts 1, a full
    screen ``FULL_SCREEN_COST``."""

    def __init__(self, model, geom: PathGeometry, st: ScreenSettings, search: ShiftSearch):
        self.model, self.geom, self.st, self.search = model, geom, st, search
        self.spent = 0

    def __call__(self, offsets, full=False):
        """The screen of each offset (dx, dy, dz mm, dyaw deg): of a subsample of the poses, or of all (``full``)."""
        self.spent += len(offsets) * (FULL_SCREEN_COST if full else 1)
        return screen_batch(self.model, self.geom, offsets, self.st, full=full)

    def out_of_time(self) -> bool:
        """True once the search has spent its budget."""
        return self.spent > self.search.budget

    def good(self, r) -> bool:
        """True when the screen ``r`` reaches every pose with the search's margins."""
        s = self.search
        return r.feasible and r.reach_used <= 1.0 - s.reach_margin and r.joint_margin >= s.joint_margin

    def confirm(self, rs):
        """The first result of rs (in order) that passes with its margins, then on every pose."""
        for r in rs:
            if self.out_of_time():
                return None
            if self.good(r):
                f = self([r.offset], full=True)[0]
                if self.good(f):
                    return f
        return None


def _first_on_shells(screens: _Screens, search: ShiftSearch):
    """(the first confirmed screen, its shell's radius mm) on shells of growing radius, each yaw in turn
    (none first), the shell's passing offsets by the reach they use; None when none within the budget."""
    dirs = directions()
    for yaw in (0.0, *search.yaws_deg):
        radii = np.arange(0.0 if yaw else search.step_mm, search.max_mm + 1e-9, search.step_mm)
        for r_mm in radii:
            if screens.out_of_time():
                break
            offs = [(*(r_mm * d), yaw) for d in (dirs if r_mm > 0 else dirs[:1])]
            offs = [tuple(round(float(v), 3) for v in o) for o in offs]
            rs = [r for r in screens(offs) if screens.good(r)]
            rs.sort(key=lambda r: (round(r.reach_used, 4), r.offset))
            f = screens.confirm(rs)
            if f is not None:
                return f, r_mm
        if screens.out_of_time():
            break
    return None


def _bisected(screens: _Screens, f, r_mm: float, step_mm: float):
    """The screen ``f`` found on the shell of radius ``r_mm``, or a nearer one: the radius bisected along its
    direction (its yaw kept) with the subsample screen, then confirmed."""
    d = np.array(f.offset[:3], float)
    if r_mm > 0:
        u = d / np.linalg.norm(d)
        lo, hi = max(r_mm - step_mm, 0.0), r_mm
        best = None
        for _ in range(5):
            if screens.out_of_time():
                break
            mid = 0.5 * (lo + hi)
            o = tuple(round(float(v), 3) for v in (*(mid * u), f.offset[3]))
            g = screens([o])[0]
            if screens.good(g):
                best, hi = g, mid
            else:
                lo = mid
        if best is not None:
            g = screens.confirm([best])
            f = g if g is not None else f
    return f


def _answer(job, r, dist, already, n, t0) -> dict:
    dx, dy, dz, dyaw = (float(v) for v in r.offset)
    xyz = [round(float(a) + b, 3) for a, b in zip(job.cell.workpiece_xyz_mm, (dx, dy, dz))]
    rr, pp, yy = (float(a) for a in job.cell.workpiece_rpy_deg)
    rpy = [rr, pp, round((yy + dyaw + 180.0) % 360.0 - 180.0, 3)]
    if dist == 0.0 and dyaw == 0.0:
        msg = (f"the closed-form screen reaches every pose at this placement (reach used {100 * r.reach_used:.1f} %), "
               "so the plan failed for another reason; camtool place searches placements with more margin")
        return {"dx_mm": 0.0, "dy_mm": 0.0, "dz_mm": 0.0, "dyaw_deg": 0.0, "distance_mm": 0.0,
                "workpiece_xyz_mm": [float(a) for a in job.cell.workpiece_xyz_mm],
                "workpiece_rpy_deg": [float(a) for a in job.cell.workpiece_rpy_deg],
                "reach_used_pct": round(100.0 * r.reach_used, 2),
                "joint_margin_pct": None if r.joint_margin is None else round(100.0 * r.joint_margin, 2),
                "poses_checked": n, "already_reachable": already, "seconds": round(time.perf_counter() - t0, 3),
                "message": msg}
    move = f"move the workpiece by ({dx:+.0f}, {dy:+.0f}, {dz:+.0f}) mm"
    if dyaw:
        move += f" and turn it {dyaw:+g} deg about world z"
    msg = (f"{move}: cell.workpiece_xyz_mm = [{', '.join(f'{v:g}' for v in xyz)}]"
           + (f", cell.workpiece_rpy_deg = [{', '.join(f'{v:g}' for v in rpy)}]" if dyaw else "")
           + " reaches every pose in the closed-form screen (camtool place searches further)")
    return {"dx_mm": round(dx, 3), "dy_mm": round(dy, 3), "dz_mm": round(dz, 3), "dyaw_deg": round(dyaw, 3),
            "distance_mm": round(dist, 3), "workpiece_xyz_mm": xyz, "workpiece_rpy_deg": rpy,
            "reach_used_pct": round(100.0 * r.reach_used, 2),
            "joint_margin_pct": None if r.joint_margin is None else round(100.0 * r.joint_margin, 2),
            "poses_checked": n, "already_reachable": already,
            "seconds": round(time.perf_counter() - t0, 3), "message": msg}
