"""The collision world (camtool.collision): obstacle specs in the job, robot bodies, the
allowed-collision matrix, coal distances, and the motion check's cell pass
(conservative advancement: nothing passes between two samples)."""
import numpy as np
import pytest
import trimesh

from camtool.collision import CellSettings, CollisionWorld, compute_acm, link_radius_mm, robot_bodies
from camtool.collision.acm import DATA_DIR, _from_json, geometry_hash
from camtool.collision.shapes import WORLD, Body
from camtool.collision.spec import obstacle_specs, parse_obstacles
from camtool.errors import BadInput
from camtool.job import load_job
from camtool.run.job_settings import JobSettings
from camtool.motion import MotionCheckSettings, PartGeometry, check_motion
from camtool.motion.cell_check import check_sampled_motion, motion_bounds
from camtool.robots import get_robot
from camtool.path.toolpath import ZONE_CODE
from camtool.transforms import matrix_from_xyz_rpy
from camtool.part.workpiece import Workpiece

Q0 = np.array([0.0, 0.3, 0.2, -0.4, 0.8, 0.1, -0.9, 0.2])
SELF = ZONE_CODE["self_motion"]


@pytest.fixture(scope="module")
def robot():
    return get_robot("seed8").with_placement(tool_T_mm=matrix_from_xyz_rpy([0, 0, 150], [0, 0, 0]))


def sphere_at(name, c, r):
    T = np.eye(4)
    T[:3, 3] = c
    return Body(name, "obstacle", WORLD, "sphere", (float(r),), T)


def box_at(name, c, size):
    T = np.eye(4)
    T[:3, 3] = c
    return Body(name, "obstacle", WORLD, "box", tuple(float(x) for x in size), T)


# --------------------------------------------------------------------------- job keys

def test_obstacles_parse_with_defaults():
    out = parse_obstacles([{"name": "table", "box_mm": [600, 1200, 40], "xyz_mm": [1, 2, 3]},
                           {"name": "post", "cylinder_mm": [30, 700], "frame": "workpiece"},
                           {"name": "ball", "sphere_mm": 50}], "job.toml: cell.obstacles")
    specs = obstacle_specs(out)
    assert [s.shape for s in specs] == ["box", "cylinder", "sphere"]
    assert specs[0].size_mm == (600.0, 1200.0, 40.0) and specs[0].xyz_mm == (1.0, 2.0, 3.0)
    assert specs[1].frame == "workpiece" and specs[2].size_mm == (50.0,)


@pytest.mark.parametrize("entry, words", [
    ({"name": "a"}, "exactly one shape key"),
    ({"name": "a", "box_mm": [1, 1, 1], "sphere_mm": 3}, "exactly one shape key"),
    ({"name": "a", "box_mm": [1, -1, 1]}, "box_mm: expected a list of 3 edge lengths"),
    ({"name": "a", "cylinder_mm": [1]}, "cylinder_mm: expected [radius, length]"),
    ({"name": "a", "sphere_mm": 0}, "sphere_mm: expected a radius"),
    ({"name": "a", "sphere_mm": 1, "frame": "robot"}, "frame: expected one of 'world', 'workpiece'"),
    ({"name": "a", "sphere_mm": 1, "units": "m"}, "units: only a mesh obstacle has units"),
    ({"name": "a", "sphere_mm": 1, "xyz": [0, 0, 0]}, "unknown key; did you mean 'xyz_mm'?"),
    ({"name": "", "sphere_mm": 1}, "name: expected a name"),
    ({"name": "a", "mesh": "f.stl", "units": "km"}, "units: expected one of"),
])
def test_bad_obstacles_name_the_entry_and_key(entry, words):
    with pytest.raises(BadInput) as e:
        parse_obstacles([entry], "job.toml: cell.obstacles")
    assert "job.toml: cell.obstacles[0]" in str(e.value) and words in str(e.value)


def test_duplicate_obstacle_names_are_refused():
    with pytest.raises(BadInput, match="names two obstacles"):
        parse_obstacles([{"name": "a", "sphere_mm": 1}, {"name": "a", "sphere_mm": 2}], "cell.obstacles")


def test_job_with_obstacles_loads_and_places_a_workpiece_fixture(tmp_path):
    (tmp_path / "part.stl").write_bytes(b"")
    job = tmp_path / "job.toml"
    job.write_text('[workpiece]\nfile = "part.stl"\n[cell]\nworkpiece_xyz_mm = [1000, 0, 0]\nfloor_z_mm = -300\n'
                   '[[cell.obstacles]]\nname = "post"\ncylinder_mm = [30, 500]\nxyz_mm = [10, 20, 30]\n'
                   'frame = "workpiece"\n')
    cell = JobSettings.from_job(load_job(job)).cell
    post, floor = cell.obstacles
    assert np.allclose(post.local_T_mm[:3, 3], [1010, 20, 30]) and post.shape == "cylinder"
    assert floor.shape == "halfspace" and floor.size_mm == (-300.0,)


def test_job_with_a_bad_obstacle_exits_with_one_line(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('[workpiece]\nfile = "part.stl"\n[[cell.obstacles]]\nname = "post"\ncylinder_mm = [30]\n')
    with pytest.raises(BadInput, match=r"cell\.obstacles\[0\] \(post\)\.cylinder_mm"):
        load_job(job)


def test_mesh_obstacle_is_its_convex_hull(tmp_path, robot):
    trimesh.creation.box(extents=(0.2, 0.2, 0.2)).export(tmp_path / "block.stl")
    job = tmp_path / "job.toml"
    job.write_text('[workpiece]\nfile = "block.stl"\n[[cell.obstacles]]\nname = "block"\nmesh = "block.stl"\n'
                   'units = "m"\nxyz_mm = [2000, 0, 0]\n')
    cell = JobSettings.from_job(load_job(job)).cell
    (block,) = cell.obstacles
    assert block.shape == "convex" and len(block.points_mm) == 8
    assert np.abs(block.points_mm).max() == pytest.approx(100.0)
    w = CollisionWorld(robot, CellSettings(obstacles=(block,)))
    ball = CollisionWorld(robot, CellSettings(obstacles=(box_at("b", [2000, 0, 0], (200, 200, 200)),)))
    assert np.allclose(w.pair_distances_mm(Q0), ball.pair_distances_mm(Q0), atol=1e-3)


# --------------------------------------------------------------------------- robot bodies

def test_seed8_bodies_come_from_its_parameters(robot):
    names = [b.name for b in robot_bodies(robot, 25.0)]
    assert names == ["carriage", "track-j2", "j4-j5", "j6-j7", "j8-flange", "tool"]
    bodies = {b.name: b for b in robot_bodies(robot, 25.0)}
    assert bodies["j4-j5"].size_mm == (link_radius_mm(400.0), 400.0) == (60.0, 400.0)
    assert bodies["track-j2"].size_mm[1] == 480.0 and bodies["tool"].size_mm == (25.0, 150.0)
    longer = get_robot("seed8", {"L2": 600.0})
    assert {b.name: b for b in robot_bodies(longer, 25.0)}["j4-j5"].size_mm == (90.0, 600.0)


def test_bodies_of_every_dh_robot_enclose_their_links():
    for name in ("irb2400_paper", "sia20_paper"):
        r = get_robot(name)
        links = [b for b in robot_bodies(r, 25.0) if b.kind == "link"]
        assert len(links) >= 3 and all(b.shape == "capsule" and 40.0 <= b.size_mm[0] <= 100.0 for b in links)


def test_manufacturer_robots_use_their_ros_industrial_meshes():
    for name, links in (("irb2400", ["link_1", "link_2", "link_3", "link_4", "link_5", "link_6"]),
                        ("sia20", ["link_s", "link_l", "link_e", "link_u", "link_r", "link_b", "link_t"])):
        bodies = robot_bodies(get_robot(name), 25.0)
        assert [b.name for b in bodies if b.kind == "link"] == links
        assert [b.name for b in bodies if b.kind == "base"] == ["base_link"]
        assert all(b.shape == "convex" for b in bodies if b.kind != "tool")


def test_a_world_of_mesh_links_pickles_as_what_it_is_made_from():
    """coal's convex shapes do not pickle; the world is rebuilt from its robot and cell (a helper process)."""
    import pickle

    w = CollisionWorld(get_robot("irb2400"), CellSettings(), 30.0)
    again = pickle.loads(pickle.dumps(w))
    assert [b.name for b in again.bodies] == [b.name for b in w.bodies] and again.pairs == w.pairs
    q = np.radians([10.0, 20.0, -15.0, 30.0, 40.0, 0.0])
    assert np.array_equal(again.valid_many(q[None]), w.valid_many(q[None]))


def test_motion_bound_holds_for_every_body_point(robot):
    """Conservative advancement rests on it: no point of a body moves farther than the bound."""
    w = CollisionWorld(robot)
    rng = np.random.default_rng(3)
    lo, hi = robot.limits.lower, robot.limits.upper
    for _ in range(20):
        qa = lo + rng.random(robot.dof) * (hi - lo)
        qb = qa + rng.normal(0, 0.05, robot.dof) * np.where(robot.prismatic, 500, 1)
        C = motion_bounds(w, np.array([qa, qb]))[1]
        Pa, Pb = w.body_poses_mm(w.joint_frames_mm(qa)), w.body_poses_mm(w.joint_frames_mm(qb))
        for b, body in enumerate(w.robot_bodies):
            r, L = (body.size_mm[0], body.size_mm[-1]) if body.shape != "box" else (0, 0)
            local = np.array([[sx * r, sy * r, sz * L / 2, 1] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            if body.shape == "box":
                local = np.array([[sx * body.size_mm[0] / 2, sy * body.size_mm[1] / 2, sz * body.size_mm[2] / 2, 1]
                                  for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
            moved = np.linalg.norm((Pa[b] @ local.T - Pb[b] @ local.T)[:3], axis=0).max()
            assert moved <= C[b] + 1e-6


def test_motion_bounds_in_blocks_are_one_cumulative_sum(robot, monkeypatch):
    """Summed a block at a time, each block carrying the sum so far: the very additions of one sum."""
    import camtool.motion.cell_check as cell_check

    w = CollisionWorld(robot)
    q = np.cumsum(np.random.default_rng(5).normal(0, 1e-3, (1001, robot.dof)), axis=0)
    whole = np.vstack([np.zeros((1, len(w.bodies))),
                       np.cumsum(np.abs(np.diff(q, axis=0)) @ cell_check.motion_rates(w), axis=0)])
    monkeypatch.setattr(cell_check, "BOUND_BLOCK_ROWS", 7)
    assert np.array_equal(motion_bounds(w, q), whole)
    assert motion_bounds(w, q[:1]).shape == (1, len(w.bodies)) and not motion_bounds(w, q[:1]).any()


# --------------------------------------------------------------------------- matrix and distances

def test_acm_is_deterministic_and_allows_adjacent_links(robot):
    bodies = robot_bodies(robot, 25.0)
    a, b = compute_acm(robot, bodies, samples=300), compute_acm(robot, bodies, samples=300)
    assert a.reasons == b.reasons
    assert a.reasons[frozenset(("j4-j5", "j6-j7"))] == "adjacent"
    assert a.reasons[frozenset(("carriage", "track-j2"))] == "adjacent"
    assert not a.allowed("carriage", "j6-j7")   # the forearm can hit the carriage


def test_shipped_acm_is_the_one_made_now(robot):
    base = get_robot("seed8")
    bodies = robot_bodies(base, 25.0)
    shipped = _from_json((DATA_DIR / "acm_seed8.json").read_text())
    assert shipped.geometry_hash == geometry_hash(base, bodies)
    assert shipped.reasons == compute_acm(base, bodies).reasons


def test_acm_overrides_and_unknown_bodies(robot):
    w = CollisionWorld(robot, CellSettings(allow=(("carriage", "j6-j7"),)))
    assert all({w.pair_name(p)[0], w.pair_name(p)[1]} != {"carriage", "j6-j7"} for p in w.pairs)
    w = CollisionWorld(robot, CellSettings(check=(("j4-j5", "j6-j7"),)))
    assert any(set(w.pair_name(p)) == {"j4-j5", "j6-j7"} for p in w.pairs)
    with pytest.raises(BadInput, match="'elbow' is not a body"):
        CollisionWorld(robot, CellSettings(allow=(("elbow", "j6-j7"),)))


def test_distance_to_a_sphere_obstacle_is_analytic(robot):
    w0 = CollisionWorld(robot)
    F = w0.joint_frames_mm(Q0)
    flange = F[-1] @ np.r_[0.0, 0.0, 150.0, 1.0]     # the j8 frame's origin + L4 along z: the flange
    c = flange[:3] + np.array([0.0, 0.0, 0.0])
    c = c + 500.0 * F[-1][:3, 0]                     # 500 mm beside the flange, square to the wrist axis
    w = CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", c, 100.0),)))
    d = dict(zip([w.pair_name(p) for p in w.pairs], w.pair_distances_mm(Q0)))
    assert d[("j8-flange", "ball")] == pytest.approx(500.0 - 100.0 - 40.0, abs=1e-6)
    assert w.valid(Q0)
    w2 = CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", c, 458.0),)))
    assert not w2.valid(Q0)


# --------------------------------------------------------------------------- the motion check's cell pass

def _far_part():
    V = np.array([[5000.0, 5000, 5000], [5100, 5000, 5000], [5000, 5100, 5000]])
    wp = Workpiece(V.mean(axis=0)[None], np.zeros((1, 3)), np.array([[0, 1, 2]]), "far", vertices_mm=V)
    return PartGeometry.from_workpiece(wp, V[:1], np.array([[0.0, 0, 1]]), grid_nodes=2000)


def test_a_thin_wall_between_two_samples_is_found(robot):
    """The track jumps 600 mm in one 4 ms step through a 2 mm wall round the TCP's midway point:
    both samples are clear, the step between them is not."""
    q = np.array([Q0 - np.r_[300.0, np.zeros(7)], Q0 + np.r_[300.0, np.zeros(7)]])
    tcp = [robot.fk_tcp(x)[:3, 3] for x in q]
    track = (tcp[1] - tcp[0]) / np.linalg.norm(tcp[1] - tcp[0])
    size = np.where(np.abs(track) > 0.5, 2.0, 40.0)
    w = CollisionWorld(robot, CellSettings(obstacles=(box_at("wall", (tcp[0] + tcp[1]) / 2.0, size),)))
    env = [p for p in w.pairs if p.kind == "environment"]
    for qq in q:
        assert w.pair_distances_mm(qq, env).min() > 100.0
    rep = check_motion([0.0, 0.004], q, [SELF, SELF], robot, _far_part(), MotionCheckSettings(), world=w)
    assert not rep.ok
    line = next(f for f in rep.findings if f.startswith("collision:"))
    assert "wall" in line and "t = 0.00" in line
    pair = next(p for p in rep.cell_pairs if p["b"] == "wall" and p["min_distance_mm"] < 0)
    assert pair["at"]["zone"] == "self_motion"


def test_a_refused_configuration_names_the_pair_that_fails(robot):
    """The planner's refusals say which bodies: the world check's reason is its closest pair."""
    from camtool.collision.validity import reason_of
    from camtool.collision.world import WorldChecker

    w0 = CollisionWorld(robot)
    F = w0.joint_frames_mm(Q0)
    c = (F[-1] @ np.r_[0.0, 0.0, 150.0, 1.0])[:3] + 100.0 * F[-1][:3, 0]
    check = WorldChecker(None, CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", c, 70.0),))))
    assert not check(Q0)
    why = reason_of(check, Q0)
    assert "ball" in why and "j8-flange" in why and "cell.clearance_mm" in why
    assert reason_of(lambda q: False, Q0) == "the validity check refuses it"


def test_sampled_motion_finds_the_thin_wall_and_clears_a_clear_one(robot):
    """The pass over sampled joint values (a simulated program) bisects between samples too, and a
    motion far from everything costs few distances."""
    q = np.array([Q0 - np.r_[300.0, np.zeros(7)], Q0 + np.r_[300.0, np.zeros(7)]])
    tcp = [robot.fk_tcp(x)[:3, 3] for x in q]
    track = (tcp[1] - tcp[0]) / np.linalg.norm(tcp[1] - tcp[0])
    size = np.where(np.abs(track) > 0.5, 2.0, 40.0)
    w = CollisionWorld(robot, CellSettings(obstacles=(box_at("wall", (tcp[0] + tcp[1]) / 2.0, size),)))
    rep = check_sampled_motion(w, q)
    hit = [c for c in rep.collisions if c[1] == "wall"]
    assert hit and hit[0][2] < 0 and 0.0 < hit[0][3] < 1.0   # between the two samples
    fine = np.array([q[0] + f * (q[1] - q[0]) for f in np.linspace(0.0, 1.0, 2001)])
    clear = CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", [1500.0, 0.0, 1500.0], 50.0),)))
    rep = check_sampled_motion(clear, fine)
    assert rep.collisions == () and rep.evaluations < 0.2 * len(fine) * len(clear.pairs)


def test_clear_motion_reports_every_pair_minimum(robot):
    ball = sphere_at("ball", [1500.0, 0.0, 1500.0], 50.0)
    w = CollisionWorld(robot, CellSettings(obstacles=(ball,)))
    t = np.linspace(0, 2.0, 11)
    q = np.tile(Q0, (11, 1))
    q[:, 0] = np.linspace(-200, 200, 11)
    rep = check_motion(t, q, np.full(11, SELF), robot, _far_part(), MotionCheckSettings(), world=w)
    assert rep.ok, rep.findings
    names = {(p["a"], p["b"]) for p in rep.cell_pairs}
    assert ("tool", "ball") in names and ("carriage", "j6-j7") in names
    # the reported minimum is within 1 mm / 10 % of the exact minimum over the samples
    qs = np.array([q[0] + f * (q[-1] - q[0]) for f in np.linspace(0, 1, 501)])
    exact = min(w.pair_distances_mm(x)[[i for i, p in enumerate(w.pairs) if w.pair_name(p) == ("tool", "ball")]][0]
                for x in qs)
    got = next(p["min_distance_mm"] for p in rep.cell_pairs if (p["a"], p["b"]) == ("tool", "ball"))
    assert exact - 1e-3 <= got <= exact + max(1.0, 0.1 * exact)


def test_urdf_robots_use_their_own_collision_elements(tmp_path):
    """A URDF's <collision> boxes and meshes become bodies on their joints (meshes as convex hulls, mm)."""
    trimesh.creation.box(extents=(0.1, 0.1, 0.4)).export(tmp_path / "forearm.stl")
    (tmp_path / "arm.urdf").write_text("""<robot name="arm">
  <link name="base"><collision><geometry><box size="0.3 0.3 0.1"/></geometry></collision></link>
  <link name="l1"><collision><origin xyz="0 0 0.2"/><geometry><mesh filename="forearm.stl"/></geometry></collision></link>
  <link name="l2"><collision><geometry><cylinder radius="0.03" length="0.2"/></geometry></collision></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" velocity="2" effort="1"/></joint>
</robot>""")
    robot = get_robot(str(tmp_path / "arm.urdf"))
    bodies = {b.parent: b for b in robot_bodies(robot, 25.0)}
    assert bodies[0].shape == "box" and bodies[0].kind == "base" and bodies[0].size_mm == pytest.approx((300, 300, 100))
    assert bodies[1].shape == "convex" and np.abs(bodies[1].points_mm).max(axis=0) == pytest.approx([50, 50, 200])
    assert bodies[1].local_T_mm[2, 3] == pytest.approx(200.0)
    assert bodies[2].shape == "cylinder" and bodies[2].size_mm == pytest.approx((30.0, 200.0))
    w = CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", [0.0, 0.0, 1000.0], 100.0),)))
    d = dict(zip([w.pair_name(p) for p in w.pairs], w.pair_distances_mm(np.zeros(2))))
    l2 = next(k for k in d if k[1] == "ball" and "l2" in k[0])
    assert d[l2] == pytest.approx(1000.0 - 400.0 - 100.0 - 100.0, abs=1e-3)   # cylinder top at z = 500


def test_missing_obstacle_mesh_is_named_at_load(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text('[workpiece]\nfile = "part.stl"\n[[cell.obstacles]]\nname = "fix"\nmesh = "nothere.stl"\n')
    with pytest.raises(BadInput, match=r"cell\.obstacles\[0\] \(fix\)\.mesh: file .*nothere\.stl not found"):
        load_job(job)


def test_sampled_motion_kept_distances_give_the_fresh_report(robot):
    """A program simulated again (the post stage's closer rounds) looks its unchanged samples' distances up
    (``cell_check._MEASURED``): its report is the one measured from nothing, whether the motion is the same,
    or changed in a stretch that now runs into a wall."""
    from camtool.motion import cell_check

    q = np.array([Q0 + f * np.r_[600.0, np.zeros(7)] for f in np.linspace(-0.5, 0.5, 3001)])
    moved = q.copy()
    moved[1400:1600, 1] += np.radians(25.0) * np.sin(np.linspace(0.0, np.pi, 200))   # into the ball there
    was, now = robot.fk_tcp(q[1500])[:3, 3], robot.fk_tcp(moved[1500])[:3, 3]
    w = CollisionWorld(robot, CellSettings(obstacles=(sphere_at("ball", now, 0.3 * np.linalg.norm(now - was)),)))

    def fresh(x):
        cell_check.forget_measured()
        return check_sampled_motion(w, x)

    for first, again in ((q, q), (q, moved), (moved, q)):
        expected = fresh(again)
        check_sampled_motion(w, first)   # kept: its distances
        got = check_sampled_motion(w, again)
        assert got.evaluations == expected.evaluations
        assert [c[:4] for c in got.collisions] == [c[:4] for c in expected.collisions]
        assert all(np.array_equal(a[4], b[4]) for a, b in zip(got.collisions, expected.collisions))
    assert fresh(moved).collisions and not fresh(q).collisions   # the stretch changed meets the ball
    cell_check.forget_measured()
