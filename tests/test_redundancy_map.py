"""The redundancy map: closed-form sweeps of the arm angle (sia20), the track (seed8) and the tool spin
(irb2400), classified by reach, joint-limit margin and manipulability, with the planned curve."""
import time
from dataclasses import replace

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.plan import plan_path
from camtool.report.redundancy_map import (
    NO_IK,
    REACHABLE,
    RedundancySettings,
    plot_redundancy_map_png,
    redundancy_kind,
    redundancy_map,
    spherical_wrist_batch,
    sweep_map,
)
from camtool.robots import get_robot
from camtool.robots.ik_spherical_wrist import SphericalWristIK
from camtool.settings import PlannerSettings
from camtool.path.toolpath import Path
from camtool.transforms import matrix_from_xyz_rpy

from plan_fixtures import sphere_rows

# each robot on a small sphere patch it reaches (the irb2400 inside its coupled axis 3, so higher than
# the serial model allowed); the irb2400's tool is tilted and offset so that a spin
# about tool z moves the wrist (with the tool on the joint-6 axis every spin is just joint 6)
CASES = {
    "sia20_paper": ("arm_angle", (1100.0, 0.0, 300.0), None),   # the sphere sits where seed 002's table reaches it
    "seed8": ("track", (1000.0, 0.0, 100.0), None),
    "irb2400": ("tool_spin", (1400.0, 0.0, 900.0), ([60.0, 0.0, 150.0], [0.0, 30.0, 0.0])),
}
SETTINGS = RedundancySettings(max_poses=60, arm_angle_step_deg=10.0, spin_step_deg=10.0, track_values=21)


def _robot(name):
    robot = get_robot(name)
    tool = CASES[name][2]
    return robot if tool is None else robot.with_placement(tool_T_mm=matrix_from_xyz_rpy(*tool))


def _path(name):
    return sphere_rows(center=CASES[name][1], rows=3, pitch_mm=20.0, el_deg=(-10, 30), az_deg=(-30, 30))


@pytest.fixture(scope="module", params=list(CASES))
def planned(request):
    name = request.param
    robot, path = _robot(name), _path(name)
    jp = plan_path(path, robot, PlannerSettings.make())
    assert jp.reached.all()
    return name, robot, path, jp, redundancy_map(path, robot, jp, SETTINGS)


def test_kind_axes_and_reachable_cells(planned):
    name, robot, path, jp, m = planned
    assert m.kind == CASES[name][0] == redundancy_kind(robot)
    assert m.code.shape == m.margin.shape == m.manipulability.shape == (len(m.y), len(m.x))
    assert len(m.x) <= SETTINGS.max_poses and np.all(path.zone[m.x] == 0)   # work poses only
    assert m.reachable.any(axis=0).all()               # every planned pose has room somewhere
    ok = m.reachable
    assert np.all((m.margin[ok] >= 0) & (m.margin[ok] <= 0.5)) and np.isnan(m.margin[~ok]).all()
    assert np.nanmax(m.manipulability) == pytest.approx(1.0) and np.nanmin(m.manipulability) > 0
    if m.kind == "track":
        assert m.y[0] == robot.limits.lower[0] and m.y[-1] == robot.limits.upper[0]
    else:
        assert m.y[0] == -180.0 and m.y[-1] < 180.0


def test_the_planned_curve_lies_on_reachable_cells(planned):
    name, robot, path, jp, m = planned
    assert np.isfinite(m.planned).all()
    rows = m.planned_rows()
    on = m.reachable[rows, np.arange(len(m.x))]
    assert on.mean() >= 0.95, f"{name}: planned curve on reachable cells {on.mean():.2f}"
    near = m.reachable[np.clip(rows - 1, 0, len(m.y) - 1), np.arange(len(m.x))] | on | \
        m.reachable[np.clip(rows + 1, 0, len(m.y) - 1), np.arange(len(m.x))]
    assert near.all()


def test_the_planned_value_is_the_planned_configuration(planned):
    """The y of the curve is the planned track / arm angle / spin (re-derived here another way)."""
    name, robot, path, jp, m = planned
    row = {int(i): k for k, i in enumerate(jp.path_index) if i >= 0}
    q = jp.q[[row[int(i)] for i in m.x]]
    if m.kind == "track":
        assert np.allclose(m.planned, q[:, 0])
    elif m.kind == "tool_spin":   # the path fixes the spin: the planner keeps it
        assert np.abs(m.planned).max() < 0.01
    else:
        from camtool.robots.ik_srs import SrsIK
        ik = SrsIK(robot)
        for y, qk, i in zip(m.planned[:5], q[:5], m.x[:5]):
            sols = ik.solve(robot.fk(qk), np.radians(y))
            assert min(np.abs(np.angle(np.exp(1j * (s.q - qk)))).max() for s in sols) < 1e-6


def test_an_unreachable_pose_gives_a_column_without_reachable_cells(planned):
    name, robot, path, jp, _ = planned
    far = path.poses_mm[len(path) // 2].copy()
    far[:3, 3] += [0.0, 0.0, 3000.0]                     # 3 m above the patch
    bad = Path(np.concatenate([path.poses_mm, far[None]]), np.append(path.segment, path.segment[-1]),
               np.append(path.point, path.point[-1] + 1), np.append(path.zone, 0).astype(path.zone.dtype))
    m = redundancy_map(bad, robot, None, SETTINGS, include=[len(path)])
    col = int(np.flatnonzero(m.x == len(path))[0])
    assert not m.reachable[:, col].any() and np.all(m.code[:, col] == NO_IK)
    assert m.reachable[:, np.arange(len(m.x)) != col].any(axis=0).all()
    assert np.isnan(m.planned).all()                     # no joint path given


def test_png(planned, tmp_path):
    name, robot, path, jp, m = planned
    f = plot_redundancy_map_png(m, tmp_path / "plots" / f"map_{name}.png")
    assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and f.stat().st_size > 10_000


def test_batched_spherical_wrist_ik_matches_the_closed_form():
    robot = get_robot("irb2400")
    ik = SphericalWristIK(robot)
    rng = np.random.default_rng(3)
    lo, hi = robot.limits.lower, robot.limits.upper
    poses = [robot.fk(lo + (hi - lo) * rng.random(6)) for _ in range(40)]
    poses.append(matrix_from_xyz_rpy([5000.0, 0.0, 0.0], [0.0, 0.0, 0.0]))   # out of reach
    with np.errstate(invalid="ignore"):
        batch = spherical_wrist_batch(ik, np.array(poses))
    assert batch.shape == (8, len(poses), 6)
    for k, T in enumerate(poses):
        got = batch[:, k][~np.isnan(batch[:, k]).any(axis=1)]
        want = ik.solve(T)
        assert len(got) == len(want)
        for s in want:
            assert np.abs(np.angle(np.exp(1j * (got - s.q)))).max(axis=1).min() < 1e-9


def test_bounded_time_on_a_15k_pose_path():
    robot = get_robot("seed8")
    path = sphere_rows(rows=32, pitch_mm=1.5, transition=2)
    assert len(path) >= 15_000
    t0 = time.perf_counter()
    m = redundancy_map(path, robot)
    seconds = time.perf_counter() - t0
    assert len(m.x) <= RedundancySettings().max_poses and m.reachable.any()
    assert seconds < 10.0, f"redundancy map of {len(path)} poses took {seconds:.1f} s"


def test_robots_without_closed_form_families_are_not_mapped():
    robot = get_robot("irb2400_paper")           # no spherical wrist
    assert redundancy_kind(robot) is None
    with pytest.raises(BadInput, match="closed-form"):
        redundancy_map(_path("sia20_paper"), robot)


def test_failing_poses_are_included_but_bounded():
    robot = get_robot("seed8")
    path = _path("seed8")
    settings = replace(SETTINGS, max_poses=20)
    m = redundancy_map(path, robot, settings=settings, include=range(0, len(path), 3))
    assert len(m.x) <= 20 and np.isin(0, m.x)
    assert m.code.dtype == np.int8 and set(np.unique(m.code)) <= {0, 1, REACHABLE}


def test_collision_layer_marks_the_cells_an_obstacle_blocks(planned):
    """An obstacle at the planned elbow blocks cells near the planned curve and nothing else changes;
    an obstacle far away changes nothing."""
    from camtool.collision import CellSettings, CollisionWorld
    from camtool.collision.shapes import WORLD, Body
    from camtool.report.redundancy_map import IN_COLLISION

    name, robot, path, jp, plain = planned
    alone = redundancy_map(path, robot, jp, SETTINGS, world=CollisionWorld(robot))   # self-collision only
    assert np.all((alone.code == plain.code) | ((plain.code == REACHABLE) & (alone.code == IN_COLLISION)))
    plain = alone
    work = np.flatnonzero(jp.path_index >= 0)
    q = jp.q[work[len(work) // 2]]
    elbow = CollisionWorld(robot).joint_frames_mm(q)[robot.dof // 2][:3, 3]   # a mid-chain joint origin
    for centre, blocks in ((elbow, True), (elbow + [0.0, 0.0, 5000.0], False)):
        T = np.eye(4)
        T[:3, 3] = centre
        world = CollisionWorld(robot, CellSettings(obstacles=(Body("ball", "obstacle", WORLD, "sphere", (120.0,), T),)))
        m = redundancy_map(path, robot, jp, SETTINGS, world=world)
        changed = m.code != plain.code
        assert np.all(plain.code[changed] == REACHABLE) and np.all(m.code[changed] == IN_COLLISION)
        assert changed.any() == blocks and (m.code == REACHABLE).any()
        if blocks:
            assert any("collision layer" in n for n in m.notes)


def _same_map(a, b):
    return all(np.array_equal(getattr(a, f), getattr(b, f), equal_nan=True)
               for f in ("x", "y", "code", "margin", "manipulability", "planned")) and a.notes == b.notes


def test_a_sweep_made_ahead_gives_the_same_map(planned):
    """The raster task sweeps the cells while the path is planned (``sweep_map``) and draws the map with
    the plan: the same map as one made at once."""
    name, robot, path, jp, m = planned
    ahead = sweep_map(path, robot, SETTINGS)
    assert ahead.serves(path, m.x, robot, SETTINGS)
    assert _same_map(redundancy_map(path, robot, jp, SETTINGS, sweep=ahead), m)


def test_a_sweep_serves_only_the_poses_it_swept(planned):
    """Leads lengthened move the work poses' indices, not the poses: the sweep still serves; other poses,
    other settings or another robot are swept again."""
    name, robot, path, jp, m = planned
    ahead = sweep_map(path, robot, SETTINGS)
    lead = np.flatnonzero(path.zone != 0)[:1]        # one more pose before the work: indices shift by one
    longer = Path(np.concatenate([path.poses_mm[lead], path.poses_mm]), np.r_[path.segment[lead], path.segment],
                  np.r_[path.point[lead], path.point], np.r_[path.zone[lead], path.zone], free_spin=path.free_spin)
    shifted = redundancy_map(longer, robot, None, SETTINGS, sweep=ahead)
    assert np.array_equal(shifted.x, m.x + 1) and np.array_equal(shifted.code, m.code)
    shift = np.zeros((4, 4))
    shift[:3, 3] = 1.0                               # 1 mm along each axis
    moved = Path(path.poses_mm + shift, path.segment, path.point, path.zone, free_spin=path.free_spin)
    assert not ahead.serves(moved, m.x, robot, SETTINGS)
    assert not ahead.serves(path, m.x, robot, replace(SETTINGS, track_values=11))
