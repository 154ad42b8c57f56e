"""Chord sag poses (camtool.plan.sag): the arc midpoint lies on spheres and cylinders, convex and concave."""
import numpy as np
import pytest

from camtool.plan.sag import arc_midpose


def pose_on_sphere(center, R, direction, outward=True):
    """A tool pose on a sphere: TCP on the surface, tool z into the material (against the outward normal)."""
    d = np.asarray(direction, float) / np.linalg.norm(direction)
    T = np.eye(4)
    T[:3, 3] = center + R * d
    z = -d if outward else d
    x = np.cross([0.0, 0.0, 1.0], z)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else np.array([1.0, 0, 0])
    T[:3, 0], T[:3, 1], T[:3, 2] = x, np.cross(z, x), z
    return T


@pytest.mark.parametrize("outward", [True, False])
def test_arc_midpoint_is_on_the_sphere(outward):
    c, R = np.array([1000.0, 0.0, 100.0]), 600.0
    a = pose_on_sphere(c, R, [-1.0, 0.0, 0.0], outward)
    b = pose_on_sphere(c, R, [-np.cos(20 / R), np.sin(20 / R), 0.0], outward)   # ~20 mm apart
    T, sag = arc_midpose(a, b)
    chord = np.linalg.norm(a[:3, 3] - b[:3, 3])
    assert sag == pytest.approx(chord ** 2 / (8 * R), rel=1e-3)           # 0.083 mm at 20 mm pitch
    assert np.linalg.norm(T[:3, 3] - c) == pytest.approx(R, abs=1e-6)     # on the surface, not on the chord
    mid_chord = 0.5 * (a[:3, 3] + b[:3, 3])
    assert np.linalg.norm(mid_chord - c) < R - 0.08                        # the chord runs behind it


def test_flat_steps_have_no_sag():
    a = np.eye(4)
    b = np.eye(4)
    b[:3, 3] = [20.0, 0, 0]
    T, sag = arc_midpose(a, b)
    assert sag == 0.0 and np.allclose(T[:3, 3], [10.0, 0, 0])


def test_batched_sags_are_the_midpose_sags():
    """The batched screen (chord_sags_mm) gives each step's own arc_midpose sag: convex, concave,
    flat and opposite tool axes."""
    from camtool.plan.sag import arc_midpose, chord_sags_mm
    from camtool.transforms import matrix_from_xyz_rpy

    rng = np.random.default_rng(4)
    Ta = np.array([matrix_from_xyz_rpy(rng.normal(0, 300, 3), rng.uniform(-180, 180, 3)) for _ in range(40)])
    Tb = np.array([a @ matrix_from_xyz_rpy(rng.normal(0, 20, 3), rng.normal(0, 5, 3)) for a in Ta])
    Tb[0] = Ta[0]                                   # no step
    Tb[1] = Ta[1].copy()
    Tb[1][:3, 3] += [5.0, 0.0, 0.0]                 # flat: parallel tool axes
    sags = chord_sags_mm(Ta, Tb)
    assert np.allclose(sags, [arc_midpose(a, b)[1] for a, b in zip(Ta, Tb)], rtol=1e-9, atol=1e-7)   # arccos of near-parallel axes: ~1e-8 mm
    assert sags[0] == 0.0 and sags[1] < 1e-7 and (sags[2:] > 1e-3).all()


def _crease_projector(slope=0.2):
    """Onto the facetted surface z = slope * |x| (a crease along y), along z: the free-form face's projection."""
    def project(p, continued=False, along=None):   # (the tool axes here are z: along them is along z)
        p = np.array(p, float)
        p[..., 2] = slope * np.abs(p[..., 0])
        return p
    return project


def _pose_at(p, z_axis=(0.0, 0.0, -1.0)):
    T = np.eye(4)
    T[:3, 3] = p
    T[:3, 2] = z_axis
    T[:3, 0] = [1.0, 0.0, 0.0]
    T[:3, 1] = np.cross(T[:3, 2], T[:3, 0])
    return T


def test_a_step_on_a_free_form_face_gets_its_midpose_on_the_facets():
    """Across a crease the arc through smoothed tool axes (here parallel: no sag) misses the facets; the face's
    own midpose lies on them, and the sag is the chord's distance from them (closed form: slope * 5 mm)."""
    from camtool.plan.sag import _arc_midposes, _surface_midposes
    project = _crease_projector(0.2)
    a, b = _pose_at([-5.0, 0.0, 1.0]), _pose_at([5.0, 0.0, 1.0])    # both on z = 0.2 |x|
    Ta, Tb = a[None], b[None]
    T_arc, sag_arc = _arc_midposes(Ta, Tb)
    assert sag_arc[0] == 0.0
    T, sag = _surface_midposes(Ta, Tb, T_arc, sag_arc, project)
    assert np.allclose(T[0, :3, 3], [0.0, 0.0, 0.0])                   # on the crease, not the chord at z = 1
    assert sag[0] == pytest.approx(1.0)


def test_a_lead_meets_the_face_above_it_keeps_the_arc_and_under_it_comes_onto_it():
    """On a ridge z = -0.2 |x| a lead's straight chord to the first work pose can run into the part: its midpose
    is then taken onto the surface; a chord that stays over it keeps the arc's midpose."""
    from camtool.plan.sag import _arc_midposes, _surface_midposes
    project = _crease_projector(-0.2)
    work = _pose_at([5.0, 0.0, -1.0])                                  # on the face
    above = _pose_at([-5.0, 0.0, 3.0])                                 # chord's midpoint 1 mm over the ridge
    under = _pose_at([-5.0, 0.0, 0.5])                                 # chord's midpoint 0.25 mm into it
    for lead, expect in ((above, None), (under, [0.0, 0.0, 0.0])):
        Ta, Tb = lead[None], work[None]
        T_arc, sag_arc = _arc_midposes(Ta, Tb)
        T, sag = _surface_midposes(Ta, Tb, T_arc, sag_arc, project)
        if expect is None:
            assert np.allclose(T, T_arc) and np.allclose(sag, sag_arc)
        else:
            assert np.allclose(T[0, :3, 3], expect) and sag[0] == pytest.approx(0.25)


def test_a_leads_dip_is_split_down_to_a_least_step_and_a_step_over_a_hole_keeps_the_arc():
    """A lead whose chord runs under the surface continued (past the face's edge: the projector NaN there, the
    continued one not) comes onto it, but a dipping step of DIP_STEP_MM or less is split no further (the Vito door's
    lead-out dipped to its very pose: halves of 0.19 mm next to a 5.9 mm step looped the time law's spline 5.45 mm
    into the door); a step between two face poses over a hole (NaN) keeps the arc, not the membrane."""
    from camtool.plan.sag import DIP_STEP_MM, _arc_midposes, _surface_midposes
    ridge = _crease_projector(-0.2)

    def project(p, continued=False, along=None):   # no face for -1 < x < 0.5 (a hole) and x < -3 (along z)
        q = ridge(p)
        x = np.asarray(p)[..., 0]
        if not continued:
            q[((x > -1.0) & (x < 0.5)) | (x < -3.0)] = np.nan
        return q
    work = _pose_at([5.0, 0.0, -1.0])
    steps = [(_pose_at([-5.0, 0.0, 0.5]), work),                      # a lead past the edge, under the ridge continued
             (_pose_at([4.4, 0.0, -0.98]), _pose_at([5.0, 0.0, -1.0])),   # 0.6 mm: dips 0.05 mm, too short to split
             (_pose_at([-2.0, 0.0, -0.4]), _pose_at([2.0, 0.0, -0.4]))]  # both on the face, the midpoint over the hole
    Ta = np.array([a for a, _ in steps])
    Tb = np.array([b for _, b in steps])
    T_arc, sag_arc = _arc_midposes(Ta, Tb)
    T, sag = _surface_midposes(Ta, Tb, T_arc, sag_arc, project)
    assert np.allclose(T[0, :3, 3], [0.0, 0.0, 0.0]) and sag[0] == pytest.approx(0.25)
    assert np.linalg.norm(Tb[1, :3, 3] - Ta[1, :3, 3]) <= DIP_STEP_MM and sag[1] == 0.0
    assert np.allclose(T[1, :3, 3], [4.7, 0.0, -0.94]) and sag_arc[1] == 0.0      # onto it, but no further split
    assert np.allclose(T[2], T_arc[2]) and sag[2] == sag_arc[2]


class _PoseSolver:
    """An arm whose joints are the pose itself (12 values: R and p): every pose solves, and the joint midpoint's TCP
    is the chord's midpoint (no bow), so a step is split only for what ``_split_steps`` itself asks."""

    lo, hi = np.full(12, -np.inf), np.full(12, np.inf)

    def solve(self, T, q0, clamp=False):
        from types import SimpleNamespace
        return SimpleNamespace(converged=True, q=np.asarray(T, float)[:3, :].ravel())

    def tcp_pose(self, q):
        T = np.eye(4)
        T[:3, :] = np.asarray(q, float).reshape(3, 4)
        return T


def _fillet_pose(angle_rad, radius_mm):
    """A pose on a fillet (a cylinder of axis y through the origin), the tool axis into the surface."""
    out = np.array([np.sin(angle_rad), 0.0, np.cos(angle_rad)])
    T = np.eye(4)
    T[:3, 1], T[:3, 2], T[:3, 3] = [0.0, 1.0, 0.0], -out, radius_mm * out
    T[:3, 0] = np.cross(T[:3, 1], T[:3, 2])
    return T


def test_a_step_round_a_tight_fillet_is_split_until_the_tool_axis_turns_at_most_the_limit():
    """Issue #46 ("no turn of more than 5 deg between neighbouring work poses"): a 5 mm step round a 10 mm fillet
    turns the tool axis 28.6 deg; its sag alone (0.31 mm, tolerance 0.05) splits it into four of 7.2 deg; the turn
    splits it into eight of 3.6 deg, each midpose on the fillet (closed form)."""
    from camtool.plan.sag import TURN_SPLIT_DEG, _split_steps

    R = 10.0

    def project(p, continued=False, along=None):   # (along the radius: the midposes' mean tool axes are radial)
        p = np.asarray(p, float)
        r = np.linalg.norm(p[:, [0, 2]], axis=1)
        out = p.copy()
        out[:, [0, 2]] *= (R / r)[:, None]
        return out

    theta = 5.0 / R
    Ta, Tb = _fillet_pose(0.0, R)[None], _fillet_pose(theta, R)[None]
    solver = _PoseSolver()
    qa, qb = Ta[:, :3, :].reshape(1, 12), Tb[:, :3, :].reshape(1, 12)
    split = _split_steps(solver, Ta, qa, Tb, qb, 0.05, 0.1, project)
    poses = [Ta[0], *(solver.tcp_pose(q) for q in split[0]), Tb[0]]
    axes = np.array([T[:3, 2] for T in poses])
    turns = np.degrees(np.arccos(np.clip(np.einsum("ki,ki->k", axes[:-1], axes[1:]), -1, 1)))
    assert len(poses) == 9 and turns.max() <= TURN_SPLIT_DEG
    np.testing.assert_allclose(turns, np.degrees(theta) / 8, atol=1e-9)
    pts = np.array([T[:3, 3] for T in poses])
    np.testing.assert_allclose(np.linalg.norm(pts[:, [0, 2]], axis=1), R, atol=1e-9)   # on the fillet
    # off the face (the projector NaN) the turn is the arc's business, not split for it
    split = _split_steps(solver, Ta, qa, Tb, qb, 0.05, 0.1, lambda p, continued=False, along=None: np.full_like(p, np.nan))
    assert len(split[0]) == 3   # the arc's sag alone: four pieces of 7.2 deg


def test_a_step_on_a_face_overhanging_its_chart_plane_gets_its_midpose_on_its_own_layer():
    """Issue #46, the ship hull's stern: a face that curls past 90 deg from its chart plane holds two layers along
    the chart's normal. Two poses on its lower layer (a cylinder R = 10 about y, at 110 and 150 deg from the top),
    their smoothed tool axes parallel (the radius at 130 deg: the arc through them has no sag): along the chart's
    normal they read as off the face (it meets the upper layer first) and the step kept its straight chord,
    R (1 - cos 20 deg) = 0.60 mm behind the surface; along their tool axes they are on it, and the midpose is taken
    onto the cylinder at 130 deg (closed form)."""
    from camtool.plan.sag import _arc_midposes, _surface_midposes

    R = 10.0

    def radial(theta_deg):
        t = np.radians(theta_deg)
        return np.array([np.sin(t), 0.0, np.cos(t)])

    def project(p, continued=False, along=None):
        p = np.array(p, float)
        if along is None:   # down the chart's normal z: the upper layer
            p[..., 2] = np.sqrt(np.maximum(R * R - p[..., 0] ** 2, 0.0))
            return p
        d = np.broadcast_to(np.asarray(along, float), p.shape)
        a = d[..., 0] ** 2 + d[..., 2] ** 2
        b = 2 * (p[..., 0] * d[..., 0] + p[..., 2] * d[..., 2])
        c = p[..., 0] ** 2 + p[..., 2] ** 2 - R * R
        root = np.sqrt(b * b - 4 * a * c)
        t = np.stack([(-b - root) / (2 * a), (-b + root) / (2 * a)])
        t = np.take_along_axis(t, np.argmin(np.abs(t), axis=0)[None], axis=0)[0]
        return p + t[..., None] * d

    axis = -radial(130.0)
    Ta, Tb = _pose_at(R * radial(110.0), axis)[None], _pose_at(R * radial(150.0), axis)[None]
    T_arc, sag_arc = _arc_midposes(Ta, Tb)
    assert sag_arc[0] == pytest.approx(0.0, abs=1e-9)
    T, sag = _surface_midposes(Ta, Tb, T_arc, sag_arc, project)
    np.testing.assert_allclose(T[0, :3, 3], R * radial(130.0), atol=1e-9)
    assert sag[0] == pytest.approx(R * (1 - np.cos(np.radians(20.0))), rel=1e-9)


def test_nearest_of_takes_each_point_onto_the_nearest_face():
    """Several free-form faces in one program (a trough and its chamfer, issue #46): the sag's projector takes each
    point onto the face whose projection lies nearest it, NaN where no face has one (without it a face set had no
    projector: its CAD faces' sag midposes stayed on the arc, 0.15-0.23 mm off the facets, and the motion check
    refused the TOOLING4G mould's trough with its chamfer)."""
    import numpy as np

    from camtool.plan.sag import nearest_of

    def floor(p, **kw):     # z = 0 for x >= 0
        q = np.array(p, float)
        q[..., 2] = 0.0
        q[q[..., 0] < 0] = np.nan
        return q

    def wall(p, **kw):      # x = 0 for z >= 0
        q = np.array(p, float)
        q[..., 0] = 0.0
        q[q[..., 2] < 0] = np.nan
        return q

    P = np.array([[5.0, 0.0, 0.2], [0.3, 0.0, 6.0], [2.0, 0.0, 1.0], [-1.0, 0.0, -1.0]])
    got = nearest_of([floor, wall])(P)
    assert np.allclose(got[:3], [[5.0, 0.0, 0.0], [0.0, 0.0, 6.0], [2.0, 0.0, 0.0]])
    assert np.isnan(got[3]).all()
