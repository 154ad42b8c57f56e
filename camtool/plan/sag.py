"""Chord sag on curved parts: intermediate poses *on the surface* between surface poses.

Between two poses on a convex part the straight chord runs behind the
surface by the sag; the controller's joint-linear motion follows that chord
(plus its own bow, kept within ``planner.chord_tol_mm`` by ``densify``). At a
20 mm pitch on a 600 mm sphere the sag alone is 0.083 mm, and with the bow the
TCP goes 0.108 mm behind the surface: more than ``check.path_tol_mm``. Here
every step between consecutive Path poses in the surface zones (lead-in, work,
lead-out) whose sag exceeds half the chord tolerance gets the arc's midpoint as
an intermediate pose, again for each half, up to ``MAX_SPLITS`` times.

The arc is the circle through both poses that meets their tool axes at right
angles (exact on spheres and cylinders, the surfaces camtool fits): with c the
chord and theta the angle between the two tool axes the sag is
c / 2 * tan(theta / 4), towards the tool where the normals diverge (convex),
away from it where they converge (concave). The orientation is slerped halfway.

On a free-form face (a mesh's own facets, or a scan's smoothed height field) the tool axes are normals
smoothed over several mm, so the arc through them is not the surface: a step's midpose is then put on
the surface itself (``project``: the chord's midpoint taken onto it along the step's mean tool axis, the
surface's normal there; along the chart's normal, a face that tilts far from its chart plane -- the hull's
stern, an 8.4 mm step whose chord ran 0.32 mm in front of it -- put the midpose 5.8 mm along the surface from
the chord, and the halves never came near its far end), and the sag
tested is the chord's own distance from the surface there (issue #46: the wavy sheet's arc midposes lay up to
0.25 mm off its facets), where both its poses lie on the face (``ON_FACE_MM``); a lead that rises off it past
its edge keeps the arc (the surface there is only continued), unless its chord runs under the surface where
it meets the face: then its midpose is taken onto the surface too (the wavy sheet's lead-ins into a trough).
A step on the face whose midpoint has no face under it (over a hole: ``project`` NaN) keeps the arc. A lead's
dip is split only down to ``DIP_STEP_MM``: a lead-out of the Vito door ran under the surface continued all the
way to its pose, so every half dipped again and the halves shrank to 0.19 mm next to its next 5.9 mm step; the
time law's cubic spline through knots so uneven, at a kink, looped 10 mm and 5.45 mm into the door.
A step on a free-form face whose tool axis turns by more than ``TURN_SPLIT_DEG`` is halved as well, whatever
its sag (a bend sharper than the pitch: a mould's fillet, a door's rolled rim), so neighbouring work poses turn
by at most that; its midpose is slerped and taken onto the face. ``camtool run`` plans a path whose work steps
are cut so already (``path.turn_split``: here a step with a retract between its poses is no step, and its turn
stayed); this split serves the paths planned as rastered (the placement search's, rastered without the part).
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from ..robots.model import Robot
from ..path.toolpath import SURFACE_CODES, Path
from ..path.turn_split import MAX_TURN_DEG, within_mm
from ..trajectory import JointPath
from .cwln import CwlnSolver
from .densify import bisected, inserted_zones, slerp_midposes
from .row_orientations import RowOrientations, along_runs

MAX_SPLITS = 3  # a step is halved at most this many times for its sag (8 pieces), twice more for its bow
ON_FACE_MM = 0.01      # a step whose poses both lie this close to a free-form face is on it (its midposes too)
DIP_STEP_MM = 1.0      # a lead step whose chord dips under a free-form face is halved down to this, no further
                       # (on the Vito door at 2 mm three 0.1-0.16 mm bows of the spline were left, at 1 mm one)
TURN_SPLIT_DEG = MAX_TURN_DEG   # a step on a free-form face whose tool axis turns more than this is halved too
                                # (issue #46; a fillet of 10 mm at a 5 mm pitch turns 29 deg)
SAG_SCREEN_MM = 1e-6   # the batched screen leaves a step to its own test unless this much within the tolerance
                       # (arccos near parallel tool axes is good to ~1e-8 rad: ~1e-7 mm of sag on a 100 mm step)


def arc_midpose(Ta: np.ndarray, Tb: np.ndarray) -> tuple[np.ndarray, float]:
    """(pose midway along the surface arc between Ta and Tb, the chord's sag in mm)."""
    T = np.eye(4)
    T[:3, :3] = Slerp([0.0, 1.0], Rotation.from_matrix([Ta[:3, :3], Tb[:3, :3]]))(0.5).as_matrix()
    T[:3, 3], sag = _arc_midpoint(Ta, Tb)
    return T, sag


def _arc_midpoint(Ta: np.ndarray, Tb: np.ndarray) -> tuple[np.ndarray, float]:
    """(the arc's midpoint (3,) mm, the chord's sag in mm) of one step."""
    pa, pb = Ta[:3, 3], Tb[:3, 3]
    za, zb = Ta[:3, 2], Tb[:3, 2]
    c = float(np.linalg.norm(pb - pa))
    theta = float(np.arccos(np.clip(za @ zb, -1.0, 1.0)))
    sag = 0.5 * c * np.tan(theta / 4.0)
    out = -(za + zb)
    n = np.linalg.norm(out)
    if n < 1e-9 or sag <= 0.0:
        return 0.5 * (pa + pb), 0.0
    out /= n
    convex = ((-zb) - (-za)) @ (pb - pa) > 0.0   # outward normals diverge along the step
    return 0.5 * (pa + pb) + (sag if convex else -sag) * out, sag


def _arc_midposes(Ta: np.ndarray, Tb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``arc_midpose`` of many steps: (m, 4, 4) poses, (m,) sags. The orientations by one batched slerp
    (``densify.slerp_midposes``, scipy's Slerp pose by pose), the points one step at a time as above."""
    T = slerp_midposes(Ta, Tb)
    sag = np.empty(len(Ta))
    for i in range(len(Ta)):
        T[i, :3, 3], sag[i] = _arc_midpoint(Ta[i], Tb[i])
    return T, sag


def chord_sags_mm(Ta: np.ndarray, Tb: np.ndarray) -> np.ndarray:
    """(K,) the chord's sag (mm) of each step Ta[k] -> Tb[k] (``arc_midpose``'s, for many steps at once)."""
    c = np.linalg.norm(Tb[:, :3, 3] - Ta[:, :3, 3], axis=1)
    theta = np.arccos(np.clip(np.einsum("ki,ki->k", Ta[:, :3, 2], Tb[:, :3, 2]), -1.0, 1.0))
    sag = 0.5 * c * np.tan(theta / 4.0)
    flat = np.linalg.norm(Ta[:, :3, 2] + Tb[:, :3, 2], axis=1) < 1e-9
    return np.where(flat | (sag <= 0.0), 0.0, sag)


def _surface_midposes(Ta, Tb, T_arc, sag_arc, project):
    """``_arc_midposes``' (m, 4, 4) midposes and (m,) sags with a free-form face's where the face decides: a step
    whose poses both lie on the face (``ON_FACE_MM``) gets the chord's midpoint taken onto the surface along the
    step's mean tool axis, its sag the chord's distance from it there; a step with one pose on it (a lead meeting
    the face) gets the same where its chord runs under the surface (into the part; the surface continued past the
    face's edge along the chart's normal, ``project(..., continued=True)``), its sag how deep (0 once the step is
    ``DIP_STEP_MM`` or shorter); the others keep the arc's, as does a step on the face whose midpoint has none under
    it (``project`` NaN: over a hole) or none within half the step (``within_mm``: a face that overhangs its
    chart plane, the hull's stern curled past 90 deg from it, holds another layer 7 mm off a 4 mm step; a midpose
    there sent the sag's halves back and forth between the layers)."""
    T, sag = T_arc.copy(), sag_arc.copy()
    pa, pb = Ta[:, :3, 3], Tb[:, :3, 3]
    on = _on_face(pa, project, Ta[:, :3, 2]).astype(int) + _on_face(pb, project, Tb[:, :3, 2])
    mid = 0.5 * (pa + pb)
    half = 0.5 * np.linalg.norm(pb - pa, axis=1)
    towards_tool = -(Ta[:, :3, 2] + Tb[:, :3, 2])
    axis = towards_tool / np.maximum(np.linalg.norm(towards_tool, axis=1), 1e-12)[:, None]
    on_face = project(mid, along=axis)
    onto = project(mid, continued=True)
    under = np.einsum("ki,ki->k", onto - mid, towards_tool) > 0.0   # the surface lies between the chord and the tool
    both, dips = (on == 2) & within_mm(on_face, mid, half), (on == 1) & under & within_mm(onto, mid, half)
    onto[both] = on_face[both]
    T[both | dips, :3, 3] = onto[both | dips]
    sag[both | dips] = np.linalg.norm(onto - mid, axis=1)[both | dips]
    sag[dips & (2.0 * half <= DIP_STEP_MM)] = 0.0
    return T, sag


def turns_on_face(Ta: np.ndarray, Tb: np.ndarray, project) -> np.ndarray:
    """(K,) whether each step lies on a free-form face (both poses within ``ON_FACE_MM`` of it) and its tool
    axis turns by more than ``TURN_SPLIT_DEG``: such a step is halved (its midpose slerped, on the face)."""
    cos = np.einsum("ki,ki->k", Ta[:, :3, 2], Tb[:, :3, 2])
    turning = cos < np.cos(np.radians(TURN_SPLIT_DEG))
    if not turning.any():
        return turning
    turning[turning] = _on_face(Ta[turning, :3, 3], project, Ta[turning, :3, 2]) \
        & _on_face(Tb[turning, :3, 3], project, Tb[turning, :3, 2])
    return turning


def step_midposes(Ta: np.ndarray, Tb: np.ndarray, project=None) -> np.ndarray:
    """(m, 4, 4) the midposes of the steps Ta[k] -> Tb[k] (base frame) as the sag takes them: on the arc through
    their tool axes (a lead's straight chord: its midpoint), on a free-form face's surface where the face
    decides (``_surface_midposes``; ``project``: base-frame points onto the face, None: an analytic face)."""
    T, sag = _arc_midposes(Ta, Tb)
    return T if project is None else _surface_midposes(Ta, Tb, T, sag, project)[0]


def _on_face(p: np.ndarray, project, axis: np.ndarray) -> np.ndarray:
    """(m,) whether each point (m, 3) lies within ``ON_FACE_MM`` of the free-form face (False where it has none),
    measured along its tool ``axis`` (m, 3): along the chart's normal a point on a layer of the face under another
    (a face that overhangs its chart plane) would read as off it."""
    with np.errstate(invalid="ignore"):
        return np.linalg.norm(project(p, along=axis) - p, axis=1) <= ON_FACE_MM


def _split_steps(solver, Ta, qa, Tb, qb, tol_mm, bow_tol_mm, project=None, orient=None) -> dict[int, np.ndarray]:
    """{step: inserted q (k, dof) in order} for the steps (Ta[i], qa[i]) -> (Tb[i], qb[i]) (base frame).

    ``densify.bisected`` with the arc's midposes (the orientations by one batched slerp a level): an interval
    whose sag exceeds ``tol_mm`` gets the arc's midpose, up to ``MAX_SPLITS`` times. A step this module splits
    is also kept within the bow tolerance, two levels more (``densify`` no longer sees it as one step of the
    Path): a half within the sag tolerance whose joint midpoint's TCP leaves the chord by more than
    ``bow_tol_mm`` is split too. ``project`` (base-frame points onto a free-form face): the face's midposes
    where it decides (``_surface_midposes``). ``orient``: ``densify.bisected``'s (the orientations of a free-form
    face's midposes along its runs' rotation splines).
    """
    def sagging(depth, Ta, qa, Tb, qb, q_mid):
        T_mid, sag = _arc_midposes(Ta, Tb)
        turning = np.zeros(len(Ta), bool)
        if project is not None:
            T_mid, sag = _surface_midposes(Ta, Tb, T_mid, sag, project)
            turning = turns_on_face(Ta, Tb, project)
        wanted = []
        for i in range(len(Ta)):
            if sag[i] <= tol_mm and not turning[i]:
                if depth == 0:
                    continue
                chord_mid = 0.5 * (Ta[i, :3, 3] + Tb[i, :3, 3])
                if np.linalg.norm(solver.tcp_pose(q_mid[i])[:3, 3] - chord_mid) <= bow_tol_mm:
                    continue
                if sag[i] <= 1e-9:
                    T_mid[i, :3, 3] = chord_mid
            wanted.append(i)
        return T_mid, wanted

    return bisected(solver, Ta, qa, Tb, qb, MAX_SPLITS + 2, sagging, orient)


def in_frame(project, base: np.ndarray):
    """``project`` (world points onto a face) for points in the frame ``base`` (4x4, world from frame)."""
    def in_frame(p, **kw):
        if kw.get("along") is not None:
            kw["along"] = kw["along"] @ base[:3, :3].T
        return (project(p @ base[:3, :3].T + base[:3, 3], **kw) - base[:3, 3]) @ base[:3, :3]
    return in_frame


def nearest_of(projectors: list):
    """A ``project`` onto several free-form faces (several in one program, ``FaceSet``): each point onto the face
    whose projection lies nearest it, NaN where none has one. The sag's own tests (``_on_face``, ``within_mm``) then
    decide as for one face; a point of an analytic face in the set lies on none of them."""
    def project(points, **kw):
        P = np.asarray(points, float)
        best, dist = np.full(P.shape, np.nan), np.full(P.shape[:-1], np.inf)
        for f in projectors:
            q = f(P, **kw)
            with np.errstate(invalid="ignore"):
                d = np.linalg.norm(q - P, axis=-1)
            nearer = np.isfinite(d) & (d < dist)
            best[nearer], dist[nearer] = q[nearer], d[nearer]
        return best
    return project


def add_surface_poses(joint_path: JointPath, path: Path, robot: Robot, solver: CwlnSolver,
                      chord_tol_mm: float, project=None, orientations: RowOrientations | None = None) -> JointPath:
    """``joint_path`` with arc-midpoint rows where a surface step's sag exceeds ``chord_tol_mm / 2``.

    ``project``: world points (m, 3) mm -> the same taken onto a free-form face (``FreeformSurface.project_mm``;
    NaN where the face has no surface under a point);
    its steps then get midposes on it (module doc); ``orientations``: their orientations along its runs' rotation
    splines (``row_orientations``; None: slerped). Inserted rows have path_index -1 and the zone of the step
    (of its lead, on a step between work and a lead); the events get ``sag_steps`` (steps split, rows inserted, the sag tolerance).
    """
    jp = joint_path
    tol = 0.5 * chord_tol_mm
    base_inv = np.linalg.inv(robot.base_T_mm)
    on = np.isin(jp.zone, SURFACE_CODES) & (jp.path_index >= 0)
    steps = np.flatnonzero(on[:-1] & on[1:] & (np.diff(jp.path_index) == 1))
    base_project = None if project is None else in_frame(project, np.asarray(robot.base_T_mm, float))
    if len(steps):   # the steps whose sag is within the tolerance are left alone, all at once
        poses = np.einsum("ij,njk->nik", base_inv, path.poses_mm)
        Ta, Tb = poses[jp.path_index[steps]], poses[jp.path_index[steps + 1]]
        sags = chord_sags_mm(Ta, Tb)
        if base_project is not None:
            T_arc = np.broadcast_to(np.eye(4), Ta.shape).copy()
            sags = _surface_midposes(Ta, Tb, T_arc, sags, base_project)[1]
            sags[turns_on_face(Ta, Tb, base_project)] = np.inf   # split for its turn whatever its sag
        steps = steps[sags > tol - SAG_SCREEN_MM]   # the rest: each step's own test below
    inserts = {}
    if len(steps):
        T = np.einsum("ij,njk->nik", base_inv, path.poses_mm[jp.path_index[np.r_[steps, steps + 1]]])
        q = np.asarray(jp.q, float)
        split = _split_steps(solver, T[:len(steps)], q[steps], T[len(steps):], q[steps + 1], tol, chord_tol_mm,
                             base_project, along_runs(orientations, jp.path_index[steps]))
        inserts = {int(steps[i]): v for i, v in sorted(split.items())}
    events = {**jp.events, "sag_steps": {"steps": len(inserts), "rows": int(sum(len(v) for v in inserts.values())),
                                         "sag_tol_mm": tol}}
    if not inserts:
        return replace(jp, events=events)
    # an inserted row of a step between work and a lead lies in the lead: the work ends at its last work pose
    # (past the part's edge a lead pose on the arc is behind the edge's tangent plane, not work)
    return jp.with_rows_inserted(inserts, inserted_zones(jp.zone, inserts), events)
