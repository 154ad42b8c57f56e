"""The independent motion check (camtool.motion): batch FK, the part's signed
distance, and the figures of check_motion against analytic geometry.

Motions are built directly in joint space. Most use the seed arm's linear
track: moving only the track translates the whole arm, so the TCP runs on a
straight line and every body keeps its shape, which makes the expected
distances analytic.
"""
import re

import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.motion import BatchFK, MotionCheckSettings, PartGeometry, WaypointIndex, check_motion
from camtool.robots import BUILTIN_ROBOTS, get_robot
from camtool.path.toolpath import ZONE_CODE
from camtool.transforms import matrix_from_xyz_rpy
from camtool.part.workpiece import Workpiece

GRID = 20_000            # small part grids keep the tests fast
R_SPHERE = 300.0
Q0 = np.array([0.0, 0.3, 0.2, -0.4, 0.8, 0.1, -0.9, 0.2])  # a seed8 pose, tool pointing away from the base
SELF, WORK, LEAD_IN = ZONE_CODE["self_motion"], ZONE_CODE["work"], ZONE_CODE["lead_in"]


# --------------------------------------------------------------------------- helpers

def frozen(*arrays):
    """Read-only copies: the check must not write into the caller's workpiece."""
    out = [np.array(a) for a in arrays]
    for a in out:
        a.setflags(write=False)
    return out


def mesh_workpiece(V, F) -> Workpiece:
    V, F = frozen(np.asarray(V, float), F)
    return Workpiece(V.mean(axis=0)[None], np.zeros((1, 3)), F, "test", vertices_mm=V)


def patch(center, n, e1, e2, a, b) -> Workpiece:
    """A rectangle (2 triangles) round ``center`` spanning +-a along e1 and +-b along e2."""
    V = np.array([center + sa * a * e1 + sb * b * e2 for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])
    return mesh_workpiece(V, [[0, 1, 2], [0, 2, 3]])


_ICO = trimesh.creation.icosphere(subdivisions=6, radius=R_SPHERE)


def sphere_cap(center, axis, half_angle_deg=50.0) -> trimesh.Trimesh:
    """An open spherical cap (radius R_SPHERE) round ``axis``: a patch, not a closed solid."""
    keep = _ICO.triangles_center @ axis > R_SPHERE * np.cos(np.radians(half_angle_deg))
    cap = trimesh.Trimesh(_ICO.vertices + center, _ICO.faces[keep], process=False)
    cap.remove_unreferenced_vertices()
    return cap


def cap_part(center, axis, cloud=False, **kw) -> PartGeometry:
    cap = sphere_cap(center, axis)
    hint = (center + R_SPHERE * axis)[None], axis[None]
    if cloud:
        pts, face = trimesh.sample.sample_surface(cap, 60_000, seed=1)
        normals = cap.face_normals[face] * np.where(np.arange(len(face)) % 2, -1.0, 1.0)[:, None]  # half flipped
        wp = Workpiece(*frozen(pts, normals))
    else:
        wp = mesh_workpiece(cap.vertices, cap.faces)
    return PartGeometry.from_workpiece(wp, *hint, grid_nodes=GRID, **kw)


def body(report, name):
    return next(b for b in report.bodies if b["name"].startswith(name))


@pytest.fixture(scope="module")
def arm():
    """seed8 with a 150 mm tool; the TCP line of the track, the tool axis and an outward
    direction o (against the tool, square to the track) at Q0."""
    robot = get_robot("seed8").with_placement(tool_T_mm=matrix_from_xyz_rpy([0, 0, 150], [0, 0, 0]))
    fk = BatchFK(robot)
    b = fk(np.array([Q0, Q0 + [1.0, 0, 0, 0, 0, 0, 0, 0]]))
    track = b.tcp[1] - b.tcp[0]
    tool_z = b.tcp_R[0][:, 2]
    o = -(tool_z - (tool_z @ track) * track)
    o /= np.linalg.norm(o)

    class Arm:
        pass

    a = Arm()
    a.robot, a.fk, a.tcp, a.track, a.tool_z, a.o = robot, fk, b.tcp[0], track, tool_z, o
    a.side = np.cross(o, track)
    a.wrist = (b.joint_origins[0, 6], b.flange[0])
    return a


def track_motion(s_values, duration_s):
    """Waypoints moving only the track through ``s_values`` (mm), evenly timed."""
    q = np.tile(Q0, (len(s_values), 1))
    q[:, 0] = s_values
    return np.linspace(0.0, duration_s, len(s_values)), q


# --------------------------------------------------------------------------- batch FK

@pytest.mark.parametrize("name", BUILTIN_ROBOTS)
def test_batch_fk_matches_pinocchio(name):
    robot = get_robot(name).with_placement(matrix_from_xyz_rpy([300, -200, 50], [5, -10, 30]),
                                           matrix_from_xyz_rpy([10, -20, 180], [0, 25, 90]))
    rng = np.random.default_rng(7)
    q = rng.uniform(robot.limits.lower, robot.limits.upper, size=(25, robot.dof))
    fk = BatchFK(robot)
    assert fk.uses_dh
    b = fk(q)
    for k in range(len(q)):
        tcp = robot.base_T_mm @ robot.fk_tcp(q[k])
        flange = robot.base_T_mm @ robot.fk(q[k])
        assert np.abs(b.tcp[k] - tcp[:3, 3]).max() < 1e-6
        assert np.abs(b.tcp_R[k] - tcp[:3, :3]).max() < 1e-9
        assert np.abs(b.flange[k] - flange[:3, 3]).max() < 1e-6
    # every joint origin, against the Pinocchio loop (the URDF fallback)
    assert np.abs(b.joint_origins - fk._pinocchio(q).joint_origins).max() < 1e-6


def test_batch_fk_urdf_falls_back_to_pinocchio(tmp_path):
    from camtool.robots.urdf import urdf_from_robot

    file = tmp_path / "arm.urdf"
    file.write_text(urdf_from_robot(get_robot("irb2400")))
    robot = get_robot(str(file)).with_placement(tool_T_mm=matrix_from_xyz_rpy([0, 0, 100], [0, 0, 0]))
    fk = BatchFK(robot)
    assert not fk.uses_dh
    q = np.random.default_rng(1).uniform(robot.limits.lower, robot.limits.upper, size=(5, robot.dof))
    got = fk(q).tcp
    want = np.array([robot.fk_tcp(x)[:3, 3] for x in q])
    assert np.abs(got - want).max() < 1e-6


# --------------------------------------------------------------------------- penetration and clearance

def test_tcp_through_a_sphere_patch_penetrates_by_the_analytic_depth(arm):
    D = 280.0  # the TCP line passes D from the centre: R - D deep at its middle
    part = cap_part(arm.tcp - D * arm.o, arm.o)
    t, q = track_motion([-150.0, 150.0], 3.0)
    rep = check_motion(t, q, [SELF, SELF], arm.robot, part)
    assert not rep.ok
    assert body(rep, "tcp")["max_penetration_mm"] == pytest.approx(R_SPHERE - D, abs=0.05)
    line = next(f for f in rep.findings if "(body: tcp" in f)
    found = re.match(r"part penetrated by ([\d.]+) mm at t = ([\d.]+) s in self_motion", line)
    depth, t_peak = map(float, found.groups())
    assert depth == pytest.approx(R_SPHERE - D, abs=0.05)  # the mesh's facets sit up to 0.02 mm inside
    assert t_peak == pytest.approx(1.5, abs=0.05)


def test_tcp_above_a_sphere_patch_has_the_analytic_clearance(arm):
    D = 320.0
    part = cap_part(arm.tcp - D * arm.o, arm.o)
    t, q = track_motion([-150.0, 150.0], 3.0)
    rep = check_motion(t, q, [SELF, SELF], arm.robot, part)
    assert rep.tcp_min_clearance_mm == pytest.approx(D - R_SPHERE, abs=0.05)
    assert rep.tcp_min_clearance_at.t_s == pytest.approx(1.5, abs=0.05)
    assert body(rep, "tcp")["max_penetration_mm"] == 0.0


def test_tcp_through_a_plane_penetrates_by_the_analytic_depth(arm):
    theta = np.radians(30.0)
    n = arm.o * np.cos(theta) - arm.track * np.sin(theta)  # the line goes behind the plane as s grows
    e1 = np.cross(n, arm.side)
    part = PartGeometry.from_workpiece(patch(arm.tcp, n, e1 / np.linalg.norm(e1), arm.side, 300, 300),
                                       arm.tcp[None], n[None], grid_nodes=GRID)
    t, q = track_motion([-150.0, 150.0], 3.0)
    rep = check_motion(t, q, [SELF, SELF], arm.robot, part)
    assert body(rep, "tcp")["max_penetration_mm"] == pytest.approx(150.0 * np.sin(theta), abs=1e-3)
    assert rep.tcp_min_clearance_mm == pytest.approx(-75.0, abs=1e-3)


def test_point_cloud_part_agrees_with_the_mesh(arm):
    center = arm.tcp - 280.0 * arm.o
    mesh, cloud = cap_part(center, arm.o), cap_part(center, arm.o, cloud=True)
    assert (mesh.kind, cloud.kind) == ("mesh", "cloud")
    # points round the cap's middle, in front and behind (half the cloud normals came flipped)
    rng = np.random.default_rng(3)
    d = arm.o + 0.5 * rng.normal(size=(2000, 3)) * [1, 1, 1]
    d /= np.linalg.norm(d, axis=1)[:, None]
    d = d[d @ arm.o > np.cos(np.radians(35))]
    p = center + d * rng.uniform(R_SPHERE - 100, R_SPHERE + 100, len(d))[:, None]
    analytic = np.linalg.norm(p - center, axis=1) - R_SPHERE
    assert np.abs(mesh.signed_distance(p) - analytic).max() < 0.05
    assert np.abs(cloud.signed_distance(p) - analytic).max() < 0.3
    t, q = track_motion([-150.0, 150.0], 3.0)
    a = check_motion(t, q, [SELF, SELF], arm.robot, mesh)
    b = check_motion(t, q, [SELF, SELF], arm.robot, cloud)
    assert b.max_penetration_mm == pytest.approx(a.max_penetration_mm, abs=0.3)
    assert body(b, "tcp")["max_penetration_mm"] == pytest.approx(body(a, "tcp")["max_penetration_mm"], abs=0.3)


# --------------------------------------------------------------------------- work deviation

def test_joint_linear_chord_bows_off_the_sphere_by_the_sagitta(arm):
    half = 100.0  # both ends on the sphere, the chord between them dips R - sqrt(R^2 - half^2)
    D = np.sqrt(R_SPHERE**2 - half**2)
    part = cap_part(arm.tcp - D * arm.o, arm.o)
    t, q = track_motion([-half, half], 1.0)
    rep = check_motion(t, q, [WORK, WORK], arm.robot, part)
    assert rep.work_deviation_mm == pytest.approx(R_SPHERE - D, abs=0.02)
    assert rep.work_deviation_at.t_s == pytest.approx(0.5, abs=0.05)
    assert not rep.ok
    assert any("behind the surface on work" in f for f in rep.findings)


def test_only_work_to_work_segments_count_as_work(arm):
    # the sphere holds the waypoints at s = 0 and 100; s = -100 is a lead-in 32 mm off it
    D = np.sqrt(R_SPHERE**2 - 50.0**2)
    part = cap_part(arm.tcp + 50.0 * arm.track - D * arm.o, arm.o)
    t, q = track_motion([-100.0, 0.0, 100.0], 2.0)
    rep = check_motion(t, q, [LEAD_IN, WORK, WORK], arm.robot, part)
    assert rep.work_deviation_mm == pytest.approx(R_SPHERE - D, abs=0.02)  # 4.2 mm, not the lead's 32
    assert rep.work_deviation_at.t_s == pytest.approx(1.5, abs=0.05)
    assert rep.work_deviation_at.zone == "work"
    by_name = check_motion(t, q, ["lead_in", "work", "work"], arm.robot, part)
    assert by_name.work_deviation_mm == rep.work_deviation_mm


# --------------------------------------------------------------------------- bodies

def test_fifty_mm_above_passes(arm):
    c = arm.tcp - 50.0 * arm.o
    part = PartGeometry.from_workpiece(patch(c, arm.o, arm.track, arm.side, 400, 300), c[None], arm.o[None],
                                       grid_nodes=GRID)
    t, q = track_motion([-100.0, 100.0], 2.0)
    rep = check_motion(t, q, [SELF, SELF], arm.robot, part)
    assert rep.ok, rep.findings
    assert rep.tcp_min_clearance_mm == pytest.approx(50.0, abs=1e-3)
    # the tool's lowest checked point: 30 mm (exempt tip) up the tool from the TCP, radius 25
    tool_end = 50.0 + 30.0 * (-arm.tool_z @ arm.o) - 25.0
    assert rep.min_clearance_mm == pytest.approx(tool_end, abs=1e-3)
    assert rep.min_clearance_at.body == "tool"
    # per body, off work: the closest body's own figure is the minimum, with where and when; a body
    # pruned as farther has only its bound, never below the minimum
    per = {b["name"]: b for b in rep.bodies}
    assert per["tool"]["min_clearance_mm"] == pytest.approx(tool_end, abs=1e-3)
    assert per["tool"]["min_clearance_at"]["zone"] == "self_motion"
    assert per["tcp"]["min_clearance_mm"] == pytest.approx(50.0, abs=1e-3)
    for b in (b for b in per.values() if b["kind"] != "tcp"):   # the TCP is measured on its own
        assert (b["min_clearance_mm"] if b["min_clearance_mm"] is not None else b["clearance_above_mm"]) \
            >= rep.min_clearance_mm - 1e-9


def test_wrist_dipping_into_the_part_fails_naming_body_and_time(arm):
    j7, flange = arm.wrist
    w = (flange - j7) / np.linalg.norm(flange - j7)
    n = np.cross(w, arm.track)
    n /= np.linalg.norm(n)
    # a small patch 40 mm beside the wrist axis where the wrist is at t = 1.2 s (track at +20 mm)
    c = (j7 + flange) / 2 + 20.0 * arm.track - 40.0 * n
    part = PartGeometry.from_workpiece(patch(c, n, arm.track, np.cross(n, arm.track), 40, 20), c[None], n[None],
                                       grid_nodes=GRID)
    t, q = track_motion([-100.0, 100.0], 2.0)
    rep = check_motion(t, q, [SELF, SELF], arm.robot, part)
    assert not rep.ok
    assert rep.max_penetration_mm == pytest.approx(60.0 - 40.0, abs=1e-3)
    at = rep.max_penetration_at
    assert at.body == "wrist (j7-flange)" and at.zone == "self_motion"
    assert 0.74 <= at.t_s <= 1.66  # some axis point over the patch
    line = next(f for f in rep.findings if "part penetrated" in f)
    assert "(body: wrist (j7-flange)" in line and f"t = {at.t_s:.3f} s in self_motion" in line
    assert body(rep, "forearm")["max_penetration_mm"] == 0.0


def test_tool_tip_is_exempt_but_not_without_the_exemption(arm):
    # the TCP on a plane square to the tool; j8 spins the tool about its own axis
    n = -arm.tool_z
    e1 = np.cross(n, arm.side)
    part = PartGeometry.from_workpiece(patch(arm.tcp, n, e1 / np.linalg.norm(e1), np.cross(n, e1 / np.linalg.norm(e1)),
                                             300, 300), arm.tcp[None], n[None], grid_nodes=GRID)
    q = np.array([Q0, Q0 + [0, 0, 0, 0, 0, 0, 0, 0.5]])
    rep = check_motion([0.0, 1.0], q, [WORK, WORK], arm.robot, part)
    assert rep.ok, rep.findings
    assert rep.work_deviation_mm == pytest.approx(0.0, abs=1e-3)
    bare = check_motion([0.0, 1.0], q, [WORK, WORK], arm.robot, part, MotionCheckSettings(tool_contact_exempt_mm=0.0))
    assert not bare.ok
    assert body(bare, "tool")["max_penetration_mm"] == pytest.approx(25.0, abs=1e-3)
    assert any("(body: tool" in f for f in bare.findings)


def test_contact_allowance_skips_the_tcp_near_a_touching_waypoint(arm):
    theta = np.radians(30.0)
    n = arm.o * np.cos(theta) + arm.track * np.sin(theta)  # the TCP rises 0.5 mm per mm of track
    e1 = np.cross(n, arm.side)
    part = PartGeometry.from_workpiece(patch(arm.tcp, n, e1 / np.linalg.norm(e1), arm.side, 300, 300),
                                       arm.tcp[None], n[None], grid_nodes=GRID)
    t, q = track_motion([0.0, 100.0], 1.0)  # 0.4 mm of track per 4 ms sample
    rep = check_motion(t, q, [WORK, SELF], arm.robot, part)
    assert rep.tcp_min_clearance_mm == pytest.approx(2.4 * 0.5, abs=1e-3)  # the first sample beyond 2 mm
    none = check_motion(t, q, [WORK, SELF], arm.robot, part, MotionCheckSettings(contact_allowance_mm=0.0))
    assert none.tcp_min_clearance_mm == pytest.approx(0.4 * 0.5, abs=1e-3)


# --------------------------------------------------------------------------- the part's signed distance

def _grid_sheet(n=21, half=200.0):
    u, v = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n), indexing="ij")
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return np.c_[u.ravel(), v.ravel(), np.zeros(n * n)], np.r_[np.c_[a, b, c], np.c_[a, c, d]]


@pytest.mark.parametrize("kind", ["mesh", "cloud"])
def test_inside_means_behind_the_patch_within_its_footprint(kind):
    V, F = _grid_sheet()
    if kind == "mesh":  # wound downwards: the hint turns it up
        wp, tol, band = mesh_workpiece(V, F[:, ::-1]), 1e-3, 0.5
    else:
        m = trimesh.Trimesh(V, F, process=False)
        pts, _ = trimesh.sample.sample_surface(m, 60_000, seed=4)
        wp, tol, band = Workpiece(*frozen(pts, np.tile([0.0, 0.0, -1.0], (len(pts), 1)))), None, 10.0
    part = PartGeometry.from_workpiece(wp, [[0.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], grid_nodes=GRID)
    tol = tol or part.lateral_tol_mm  # a cloud's edge is as sharp as its sampling
    p = np.random.default_rng(8).uniform([-320, -320, -250], [320, 320, 250], (20_000, 3))
    over = np.abs(p[:, :2]).max(axis=1) - 200.0  # > 0: beyond the footprint
    p = p[np.abs(over) > band]  # the edge itself is a matter of tolerance
    over = over[np.abs(over) > band]
    dist = np.linalg.norm(p - np.c_[np.clip(p[:, :2], -200, 200), np.zeros(len(p))], axis=1)
    want = np.where((over < 0) & (p[:, 2] < 0), -dist, dist)
    assert np.abs(part.signed_distance(p) - want).max() < tol
    # a closed box: the side at its corners and edges (float32 closest points land on any face there)
    box = trimesh.creation.box([300, 300, 300])
    part = PartGeometry.from_workpiece(mesh_workpiece(box.vertices, box.faces), grid_nodes=GRID)
    p = np.random.default_rng(9).uniform(-250, 250, (20_000, 3))
    p[:5000, 0] = 150.0  # in a face's plane
    q = np.abs(p) - 150.0
    want = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
    assert np.abs(part.signed_distance(p) - want).max() < 0.25


# --------------------------------------------------------------------------- the pruning is exact

def test_pruning_changes_no_figure(arm, monkeypatch):
    j7, flange = arm.wrist
    w = (flange - j7) / np.linalg.norm(flange - j7)
    n = np.cross(w, arm.track)
    n /= np.linalg.norm(n)
    c = (j7 + flange) / 2 + 20.0 * arm.track - 50.0 * n  # the wrist 10 mm into it
    part = PartGeometry.from_workpiece(patch(c, n, arm.track, np.cross(n, arm.track), 200, 60), c[None], n[None],
                                       grid_nodes=GRID)
    t, q = track_motion([-100.0, 0.0, 100.0], 2.0)
    zones = [SELF, WORK, SELF]
    fast = check_motion(t, q, zones, arm.robot, part)
    monkeypatch.setattr(PartGeometry, "lower_bound", lambda self, p, h: np.full(len(p), -np.inf))
    monkeypatch.setattr(PartGeometry, "above", lambda self, p, h, level: np.zeros(len(p), bool))
    slow = check_motion(t, q, zones, arm.robot, part)
    for key in ("max_penetration_mm", "min_clearance_mm", "tcp_min_clearance_mm", "work_deviation_mm"):
        assert getattr(fast, key) == pytest.approx(getattr(slow, key), abs=1e-9), key
    assert fast.findings == slow.findings


@pytest.mark.parametrize("kind", ["mesh", "cloud"])
def test_lower_bound_never_exceeds_the_value(kind):
    """The grid's bound over a ball is below the value at every point of the ball: an open
    bent sheet (edges and a crease) and a closed box."""
    u, v = np.meshgrid(np.linspace(-200, 200, 21), np.linspace(-200, 200, 21), indexing="ij")
    x = u.ravel()
    sheet = np.c_[np.minimum(x, 0), v.ravel(), np.where(x > 0, -x, 0)]
    idx = np.arange(441).reshape(21, 21)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    box = trimesh.creation.box([300, 300, 300])
    cases = [(sheet, np.r_[np.c_[a, b, c], np.c_[a, c, d]], ([[-100, 0, 10], [100, 0, -10]], [[0, 0, 1], [1, 0, 0]])),
             (box.vertices, box.faces, (None, None))]
    rng = np.random.default_rng(11)
    for V, F, hint in cases:
        if kind == "mesh":
            wp = mesh_workpiece(V, F)
        else:
            m = trimesh.Trimesh(V, F, process=False)
            pts, face = trimesh.sample.sample_surface(m, 40_000, seed=2)
            wp = Workpiece(np.asarray(pts), m.face_normals[face])
        part = PartGeometry.from_workpiece(wp, *hint, grid_nodes=GRID)
        p = rng.uniform(-600, 600, (6000, 3))
        h = rng.uniform(0, 150, len(p))
        lb = part.lower_bound(p, h)
        assert np.isfinite(lb).mean() > 0.3  # the grid does prune
        level = rng.uniform(0, 200, len(p))
        above = part.above(p, h, level)
        assert above.mean() > 0.1  # it prunes
        for _ in range(4):
            e = rng.normal(size=p.shape)
            e /= np.linalg.norm(e, axis=1)[:, None]
            inside = p + e * (h * rng.uniform(0, 1, len(p)) ** (1 / 3))[:, None]
            value = part.signed_distance(inside)
            assert (value >= lb - 1e-9).all()
            assert (value[above] > level[above]).all()


# --------------------------------------------------------------------------- input and report

def test_bad_input_is_one_clear_line(arm):
    part = cap_part(arm.tcp - 320.0 * arm.o, arm.o)
    t, q = track_motion([0.0, 10.0], 1.0)
    with pytest.raises(BadInput, match="unknown zone 'milling'"):
        check_motion(t, q, ["work", "milling"], arm.robot, part)
    with pytest.raises(BadInput, match="must increase"):
        check_motion([0.0, 0.0], q, [WORK, WORK], arm.robot, part)
    with pytest.raises(BadInput, match="q has shape"):
        check_motion(t, q[:, :7], [WORK, WORK], arm.robot, part)
    with pytest.raises(BadInput, match="clearance_mm"):
        MotionCheckSettings(clearance_mm=-1.0)


def test_report_to_dict_is_json(arm):
    import json

    part = cap_part(arm.tcp - 280.0 * arm.o, arm.o)
    t, q = track_motion([-150.0, 0.0, 150.0], 3.0)
    rep = check_motion(t, q, [SELF, SELF, SELF], arm.robot, part, index=WaypointIndex([-1, 7, 8], "segment"))
    d = json.loads(json.dumps(rep.to_dict()))
    assert d["samples"] == 751 and d["dt_s"] == 0.004
    assert d["max_penetration_at"]["index_label"] == "segment"
    assert any("before segment 8" in f or "at segment 7" in f or "before segment 7" in f for f in d["findings"])


def test_shares_no_code_with_planner_or_timing():
    import ast
    import subprocess
    import sys
    from pathlib import Path

    forbidden = ("camtool.plan", "camtool.timing", "camtool.run.pipeline", "camtool.path.raster", "camtool.part.fit",
                 "camtool.run.stages")
    for file in (Path(__file__).resolve().parents[1] / "camtool" / "motion").glob("*.py"):
        for node in ast.walk(ast.parse(file.read_text())):
            if isinstance(node, ast.ImportFrom):
                module = node.module or ""
                name = {0: module, 1: "camtool.motion." + module}.get(node.level, "camtool." + module)
                assert not name.startswith(forbidden), f"{file.name} imports {name}"
            elif isinstance(node, ast.Import):
                assert not any(a.name.startswith(forbidden) for a in node.names), file.name
    code = ("import sys, camtool.motion; "
            f"print([m for m in sys.modules if m.startswith({forbidden!r})])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_figures_by_index_add_up_to_the_whole_check(arm):
    """``by_index``: each caller's index gets its samples' worst figures; together they are the check's."""
    part = cap_part(arm.tcp - 280.0 * arm.o, arm.o)
    t, q = track_motion([-150.0, 0.0, 150.0], 3.0)
    rep = check_motion(t, q, [SELF, SELF, SELF], arm.robot, part, index=WaypointIndex([-1, 7, 8], "segment"))
    rows = {r["index"]: r for r in rep.to_dict()["by_index"]}
    assert set(rows) == {7, 8}
    assert sum(r["samples"] for r in rows.values()) == rep.samples
    assert max(r["max_penetration_mm"] for r in rows.values()) == pytest.approx(rep.max_penetration_mm, abs=1e-6)
    failing = sum(sum(r["failing_samples"].values()) for r in rows.values())
    assert (failing > 0) == bool(rep.findings)
    assert check_motion(t, q, [SELF, SELF, SELF], arm.robot, part).by_index == ()  # no index: none


def test_a_scans_noise_and_blended_edge_normals_do_not_read_as_behind():
    """On a noisy scan (sigma 0.1 mm, normals estimated from 30 neighbours as a scanner's software does) a point
    on the surface is measured from the plane of its nearest points: a 5-sigma stray point above it, or a
    point 2.5 mm from a convex edge whose normals blend, reads within 0.15 mm of zero; 1 mm under it reads
    -1 mm."""
    import open3d as o3d

    rng = np.random.default_rng(7)
    g = np.arange(-30.0, 30.0, 1.2)
    X, Y = np.meshgrid(g, g)
    flat = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    slope = np.c_[30.0 + np.arange(0.6, 20, 1.2)[:, None].repeat(len(g), 1).ravel() / np.sqrt(2), np.tile(g, 17),
                  -np.arange(0.6, 20, 1.2)[:, None].repeat(len(g), 1).ravel() / np.sqrt(2)]
    pts = np.vstack([flat, slope]) + rng.normal(0, 0.1, (len(flat) + len(slope), 3))
    pts[0] = [-30.0, -30.0, 0.0]
    stray = np.flatnonzero(np.linalg.norm(flat[:, :2] - [0.0, 0.0], axis=1) < 0.1)[0]
    pts[stray, 2] = 0.5
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=30))
    normals = np.asarray(pc.normals)
    normals[normals[:, 2] < 0] *= -1
    part = PartGeometry.from_workpiece(Workpiece(pts, normals), np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 1]]),
                                       grid_nodes=GRID)
    on = np.array([[0.0, 0.0, 0.0], [27.5, 0.0, 0.0], [27.5, 6.0, 0.0], [10.0, 10.0, 0.0]])
    assert np.all(np.abs(part.signed_distance(on)) < 0.15)
    assert part.signed_distance(np.array([[10.0, -10.0, -1.0]]))[0] == pytest.approx(-1.0, abs=0.1)


def test_a_stray_scan_point_within_the_fit_band_does_not_tilt_the_local_plane():
    """Issue #48 (samples/sia20_wall.toml): wall.ply's outliers within 3 x fit.threshold_mm stay in the checked
    part; one 4.2 mm behind the wall among points 0.1 mm off it tilted the plane of the 8 nearest points and read
    the TCP on a target of the wall as 1.8 mm behind it. The stray point is left out of that plane; a pose 1 mm
    behind still reads -1 mm, and a noise-free curved cloud reads as before."""
    rng = np.random.default_rng(3)
    g = np.arange(-40.0, 40.0, 4.0)
    X, Y = np.meshgrid(g, g)
    pts = np.c_[X.ravel() + 1.0, Y.ravel() + 0.7, rng.normal(0, 0.1, X.size)]
    pts = np.vstack([pts, [[-2.0, 3.5, -4.25], [5.0, -4.0, 5.0]]])  # two strays round the origin
    normals = np.tile([0.0, 0.0, 1.0], (len(pts), 1))
    part = PartGeometry.from_workpiece(Workpiece(pts, normals), np.array([[0.0, 0, 0]]), np.array([[0.0, 0, 1]]),
                                       grid_nodes=GRID)
    on = np.array([[0.0, 0.0, 0.0], [-1.0, 2.0, 0.0], [4.0, -3.0, 0.0], [-3.0, 4.5, 0.0]])
    assert np.all(np.abs(part.signed_distance(on)) < 0.2), part.signed_distance(on)
    assert part.signed_distance(np.array([[0.0, 0.0, -1.0]]))[0] == pytest.approx(-1.0, abs=0.2)
    # a sphere of 100 mm sampled without noise: the plane of all 8 neighbours, so the offset of its chord
    u, v = np.meshgrid(np.linspace(-0.4, 0.4, 40), np.linspace(-0.4, 0.4, 40))
    s = 100.0 * np.c_[np.sin(u.ravel()) * np.cos(v.ravel()), np.sin(v.ravel()), np.cos(u.ravel()) * np.cos(v.ravel())]
    part = PartGeometry.from_workpiece(Workpiece(s, s / 100.0), np.array([[0.0, 0, 100]]), np.array([[0.0, 0, 1]]),
                                       grid_nodes=GRID)
    q = np.array([[0.0, 0.0, 100.0], [10.0, 5.0, np.sqrt(100.0**2 - 125.0)]])
    assert np.all(np.abs(part.signed_distance(q)) < 0.05), part.signed_distance(q)


def test_a_face_beside_an_edge_is_not_a_stray_point():
    """The stray-point rule leaves a chamfer's points alone: each lies on the plane of its own neighbours
    (samples/plate_chamfer_scan.toml's leads run over such an edge)."""
    rng = np.random.default_rng(5)
    g = np.arange(0.0, 40.0, 2.0)
    X, Y = np.meshgrid(g, np.arange(-20.0, 20.0, 2.0))
    flat = np.c_[X.ravel(), Y.ravel(), np.zeros(X.size)]
    d = np.arange(1.0, 15.0, 2.0)
    D, Yc = np.meshgrid(d, np.arange(-20.0, 20.0, 2.0))
    chamfer = np.c_[40.0 + D.ravel() / np.sqrt(2), Yc.ravel(), -D.ravel() / np.sqrt(2)]
    pts = np.vstack([flat, chamfer]) + rng.normal(0, 0.02, (len(flat) + len(chamfer), 3))
    normals = np.vstack([np.tile([0.0, 0.0, 1.0], (len(flat), 1)), np.tile([0.5 ** 0.5, 0.0, 0.5 ** 0.5], (len(chamfer), 1))])
    part = PartGeometry.from_workpiece(Workpiece(pts, normals), np.array([[20.0, 0, 0]]), np.array([[0.0, 0, 1]]),
                                       grid_nodes=GRID)
    assert not part._isolated(np.arange(len(flat), len(pts))).any()
    assert not part._isolated(np.arange(len(flat))).any()


def test_noisy_cloud_edge_reads_beside_it_in_front_and_below_it_behind():
    """Issue #46: at the edge of a noisy scan (1 mm) whose file normals there are 60 deg off (estimated over a
    one-sided neighbourhood), a point 4 mm beyond the edge and 1 mm above the plane is not read behind the part by
    more than the noise band (the
    normals of the edge come from the checked points' own plane), while points 4 mm under the plane inside it
    still are (independent reference: the plane z = 0)."""
    rng = np.random.default_rng(46)
    xy = rng.uniform(0.0, 80.0, (8000, 2))
    P = np.column_stack([xy, rng.normal(0.0, 1.0, len(xy))])
    N = np.tile([0.0, 0.0, 1.0], (len(P), 1))
    rim = xy[:, 0] > 77.0                                     # the file's normals at the x = 80 edge: 60 deg off
    N[rim] = [np.sin(np.radians(-60.0)), 0.0, np.cos(np.radians(60.0))]
    part = PartGeometry.from_workpiece(Workpiece(P, N, source="scan.ply"), np.array([[40.0, 40.0, 0.0]]),
                                       np.array([[0.0, 0.0, 1.0]]))
    beside = np.column_stack([np.full(20, 84.0), np.linspace(10.0, 70.0, 20), np.full(20, 1.0)])
    assert part.signed_distance(beside).min() > -3.0   # within the noise band (3 sigma), the check's scan tolerance
    under = np.column_stack([rng.uniform(10.0, 70.0, (50, 2)), np.full(50, -4.0)])
    assert part.signed_distance(under).max() < -1.0


# --------------------------------------------------------------------------- scanned meshes (issue #46)

def _sheet_mesh(arm, heights_mm, spacing_mm=2.0, half=(130.0, 30.0)):
    """A triangulated sheet through the TCP, square to o, rows along the track: vertex k at height
    heights_mm(u, v) along o (u along the track, v along the side)."""
    u = np.arange(-half[0], half[0] + 1e-9, spacing_mm)
    v = np.arange(-half[1], half[1] + 1e-9, spacing_mm)
    U, W = np.meshgrid(u, v)
    H = heights_mm(U, W)
    V = arm.tcp + U.ravel()[:, None] * arm.track + W.ravel()[:, None] * arm.side + H.ravel()[:, None] * arm.o
    nu = len(u)
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(len(v) - 1))
    a = (j * nu + i).ravel()
    F = np.r_[np.c_[a, a + 1, a + nu + 1], np.c_[a, a + nu + 1, a + nu]]
    return mesh_workpiece(V, F)


def _work_check(arm, wp, band_mm):
    part = PartGeometry.from_workpiece(wp, arm.tcp[None], arm.o[None], grid_nodes=GRID)
    t, q = track_motion(np.arange(-100.0, 100.0 + 1e-9, 5.0), 4.0)   # work poses 5 mm apart on the mean plane
    return check_motion(t, q, np.full(len(t), WORK), arm.robot, part, MotionCheckSettings(scan_band_mm=band_mm))


def test_a_scanned_meshs_bumps_pass_within_its_noise_band_and_fail_without(arm):
    from camtool.run.stages import scanned_mesh_band_mm

    rng = np.random.default_rng(46)
    wp = _sheet_mesh(arm, lambda U, W: rng.normal(0.0, 0.06, U.shape))     # a scan's roughness, 0.06 mm RMS
    band = scanned_mesh_band_mm(wp)
    assert 0.15 < band < 0.3
    strict = _work_check(arm, wp, 0.0)
    assert not strict.ok and strict.max_penetration_mm > 0.1              # the bumps rise over the moves
    banded = _work_check(arm, wp, band)
    assert banded.ok, banded.findings
    assert banded.max_penetration_mm == pytest.approx(strict.max_penetration_mm)   # the same figure, judged by the band
    assert scanned_mesh_band_mm(wp, scan="no") == 0.0     # workpiece.scan = "no": a CAD mesh, strict


def test_a_cad_meshs_real_step_still_fails(arm):
    from camtool.run.stages import scanned_mesh_band_mm

    wp = _sheet_mesh(arm, lambda U, W: np.where(U > 40.0, 0.15, 0.0))    # a real 0.15 mm step, flat elsewhere
    assert scanned_mesh_band_mm(wp) == 0.0                               # smooth vertices: CAD, strict
    rep = _work_check(arm, wp, scanned_mesh_band_mm(wp))
    assert not rep.ok
    assert rep.max_penetration_mm == pytest.approx(0.15, abs=0.01)
    assert any("part penetrated by 0.15" in f and "noise band" not in f for f in rep.findings)


def test_a_finding_beyond_the_noise_band_names_it(arm):
    rng = np.random.default_rng(46)
    wp = _sheet_mesh(arm, lambda U, W: rng.normal(0.0, 0.06, U.shape) + np.where(U > 40.0, 0.6, 0.0))
    rep = _work_check(arm, wp, 0.2)
    assert not rep.ok
    assert any("beyond the scan's noise band: 0.1 + 0.200 mm" in f for f in rep.findings)
