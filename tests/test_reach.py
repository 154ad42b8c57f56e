"""Seed 002's sequential reaching task: the target plane, the S-ordered grid and the family table."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.job import load_job
from camtool.plan.arm_angle_sqp import ArmAngleResult, FamilyResult
from camtool.part.surface import Boundary, PlaneSurface, SpherePatch
from camtool.run.tasks.reach import family_table_text, reach_path, target_plane
from camtool.path.toolpath import ZONE_CODE

WORK, APPROACH = ZONE_CODE["work"], ZONE_CODE["approach"]


def vec(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def write_job(tmp_path, base=(0.0, 100.0, 0.0), plane="job", **task):
    """A sequential_reach job (plane = 'job' by default, so no workpiece is read)."""
    t = {"plane_point_mm": (0.0, 600.0, 0.0), "plane_normal": (0.0, 1.0, 0.0)}
    t.update(task)
    lines = ["[workpiece]", 'file = "wall.ply"', "[robot]", 'name = "sia20"', "[cell]",
             f"base_xyz_mm = {vec(base)}", "[planner]", 'method = "arm-angle-sqp"', "[task]",
             'kind = "sequential_reach"', f'plane = "{plane}"']
    for k, v in t.items():
        lines.append(f"{k} = " + (f'"{v}"' if isinstance(v, str) else repr(v) if isinstance(v, (int, float))
                                  else vec(v)))
    f = tmp_path / "reach.toml"
    f.write_text("\n".join(lines) + "\n")
    return load_job(f)


def build(job):
    point, normal = target_plane(job)
    return reach_path(job, point, normal, job.cell.base_xyz_mm)


def xyz(path):
    return path.poses_mm[:, :3, 3]


# -- the paper's grid ------------------------------------------------------------------
def test_default_grid_is_the_papers_8_by_8_wall(tmp_path):
    job = write_job(tmp_path)  # defaults: origin (-350, 600, 250), step 100, start (350, 600, 950)
    path = build(job)
    assert len(path) == 64  # the start is the corner target: no extra start pose
    p = xyz(path)
    expected = {(-350.0 + 100 * m, 600.0, 250.0 + 100 * n) for m in range(8) for n in range(8)}
    assert {tuple(np.round(r, 9)) for r in p} == expected
    assert np.allclose(p[0], [350, 600, 950])  # begins at the start corner
    assert np.allclose(np.linalg.norm(np.diff(p, axis=0), axis=1), 100.0)  # S order: every move one step
    assert np.all(path.zone == WORK) and np.all(path.point == 1)
    assert np.array_equal(path.segment, np.arange(64))  # one single-pose run per target
    assert path.step_over_mm == 100.0 and path.pitch_mm == 100.0


def test_tool_axes_face_the_wall(tmp_path):
    path = build(write_job(tmp_path))
    R = path.poses_mm[:, :3, :3]
    assert np.allclose(R[:, :, 2], [0, 1, 0])    # tool z: the wall normal, away from the base at y = 100
    assert np.allclose(R[:, :, 1], [0, 0, 1])    # tool y: world z (task.tool_y_world)
    assert np.allclose(R[:, :, 0], [-1, 0, 0])   # x = y cross z
    assert np.allclose(np.linalg.det(R), 1.0)
    assert np.allclose(path.poses_mm[:, 3], [0, 0, 0, 1])


def test_horizontal_route_sweeps_rows(tmp_path):
    p = xyz(build(write_job(tmp_path, route="horizontal")))
    rows = p.reshape(8, 8, 3)
    assert np.allclose(rows[:, :, 2], rows[:, :1, 2])  # each row at one height
    assert np.allclose(rows[:, 0, 2], 950 - 100 * np.arange(8))  # from the top (the start corner) down
    dx = np.diff(rows[:, :, 0], axis=1)
    assert np.allclose(dx[0::2], -100) and np.allclose(dx[1::2], 100)  # alternate direction: an S


def test_vertical_route_sweeps_columns(tmp_path):
    p = xyz(build(write_job(tmp_path, route="vertical")))
    cols = p.reshape(8, 8, 3)
    assert np.allclose(cols[:, :, 0], cols[:, :1, 0])  # each column at one x
    assert np.allclose(cols[:, 0, 0], 350 - 100 * np.arange(8))
    dz = np.diff(cols[:, :, 2], axis=1)
    assert np.allclose(dz[0::2], -100) and np.allclose(dz[1::2], 100)


SMALL = dict(grid_origin_mm=(0.0, 600.0, 0.0), grid_step_mm=50.0, grid_columns=3, grid_rows=2)


@pytest.mark.parametrize("route, start, order", [
    ("horizontal", (100.0, 600.0, 0.0), [(100, 0), (50, 0), (0, 0), (0, 50), (50, 50), (100, 50)]),
    ("vertical", (100.0, 600.0, 0.0), [(100, 0), (100, 50), (50, 50), (50, 0), (0, 0), (0, 50)]),
    ("horizontal", (0.0, 600.0, 50.0), [(0, 50), (50, 50), (100, 50), (100, 0), (50, 0), (0, 0)]),
    ("vertical", (0.0, 600.0, 0.0), [(0, 0), (0, 50), (50, 50), (50, 0), (100, 0), (100, 50)]),
])
def test_small_grid_order_from_each_corner(tmp_path, route, start, order):
    path = build(write_job(tmp_path, route=route, start_mm=start, **SMALL))
    assert len(path) == 6
    assert np.allclose(xyz(path)[:, [0, 2]], order)
    assert np.allclose(xyz(path)[:, 1], 600.0)


def test_start_off_the_grid_is_a_separate_approach_pose(tmp_path):
    # 40 mm in front of the wall and off the grid, nearest to the (0, 0) corner
    path = build(write_job(tmp_path, start_mm=(-420.0, 560.0, 190.0)))
    assert len(path) == 65
    assert np.allclose(xyz(path)[0], [-420, 600, 190])  # projected onto the plane
    assert path.zone[0] == APPROACH and path.point[0] == 0
    assert np.all(path.zone[1:] == WORK) and np.all(path.point[1:] == 1)
    assert np.allclose(xyz(path)[1], [-350, 600, 250])  # then the nearest corner
    assert np.allclose(path.poses_mm[0, :3, :3], path.poses_mm[1, :3, :3])
    assert np.array_equal(path.segment, np.arange(65))


def test_start_within_a_micrometre_of_the_first_target_is_that_target(tmp_path):
    path = build(write_job(tmp_path, start_mm=(350.0, 600.0, 950.0 + 5e-4)))
    assert len(path) == 64 and path.zone[0] == WORK


@pytest.mark.xfail(strict=True, reason="BUG: the sweep starts from the corner on the side of the grid point "
                   "nearest to the start (m0 == 0 or not), not from the nearest corner the docs promise")
def test_sweep_begins_at_the_corner_nearest_to_the_start(tmp_path):
    # start on grid point (m=2, n=0): corner (0, 0) is 200 mm away, corner (7, 0) 500 mm
    path = build(write_job(tmp_path, start_mm=(-150.0, 600.0, 250.0)))
    assert path.zone[0] == APPROACH
    assert np.allclose(xyz(path)[1], [-350, 600, 250])


# -- other planes ----------------------------------------------------------------------
def test_normal_sign_does_not_matter(tmp_path):
    a = build(write_job(tmp_path, plane_normal=(0.0, 1.0, 0.0)))
    b = build(write_job(tmp_path, plane_normal=(0.0, -3.0, 0.0)))
    assert np.allclose(a.poses_mm, b.poses_mm)


def test_tool_z_points_away_from_a_base_behind_the_wall(tmp_path):
    # (the grid's m direction h = -tool x flips with the tool z, so the grid is mirrored about its
    # origin and the start is no longer a corner; only what holds either way is checked here)
    path = build(write_job(tmp_path, base=(0.0, 1500.0, 0.0)))
    assert np.allclose(path.poses_mm[:, :3, 2], [0, -1, 0])
    assert np.allclose(xyz(path)[:, 1], 600.0)
    work = xyz(path)[path.zone == WORK]
    assert len(work) == 64
    assert np.allclose(np.linalg.norm(np.diff(work, axis=0), axis=1), 100.0)
    assert np.any(np.all(np.isclose(work, [-350, 600, 250]), axis=1))  # the grid origin is a target
    assert np.allclose(np.linalg.det(path.poses_mm[:, :3, :3]), 1.0)


def test_oblique_plane_grid(tmp_path):
    n_raw = np.array([0.3, 1.0, 0.2])
    point = np.array([50.0, 600.0, 20.0])
    base = np.array([0.0, 0.0, 400.0])
    job = write_job(tmp_path, base=base, plane_point_mm=point, plane_normal=n_raw, grid_columns=4, grid_rows=3,
                    grid_step_mm=80.0, grid_origin_mm=(-100.0, 650.0, 300.0), start_mm=(-100.0, 650.0, 300.0))
    path = build(job)
    n = n_raw / np.linalg.norm(n_raw)
    p = xyz(path)
    assert len(path) == 12
    assert np.allclose((p - point) @ n, 0.0, atol=1e-9)  # every target on the plane
    origin = np.array([-100.0, 650.0, 300.0])
    origin = origin - ((origin - point) @ n) * n
    assert np.allclose(p[0], origin)  # the start (the grid origin) projected: the first target
    assert np.allclose(np.linalg.norm(np.diff(p, axis=0), axis=1), 80.0)
    R = path.poses_mm[0, :3, :3]
    assert np.allclose(R.T @ R, np.eye(3)) and np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R[:, 2], n) and (p[0] - base) @ R[:, 2] > 0  # away from the base
    y = np.array([0, 0, 1.0]) - n[2] * n
    assert np.allclose(R[:, 1], y / np.linalg.norm(y))  # world z projected onto the plane
    assert np.allclose(path.poses_mm[:, :3, :3], R)  # one orientation for every target
    # rows (horizontal route): n fixed per row, so consecutive targets in a row differ along tool x
    d = np.diff(p[:4], axis=0)
    assert np.allclose(np.abs(d @ R[:, 0]), 80.0) and np.allclose(d @ R[:, 1], 0.0, atol=1e-9)
    assert np.allclose(p[4] - p[3], 80.0 * R[:, 1])  # the next row: one step along tool y


def test_tool_y_along_the_normal_is_bad_input(tmp_path):
    job = write_job(tmp_path, tool_y_world=(0.0, 2.0, 0.0))
    with pytest.raises(BadInput, match="tool_y_world"):
        build(job)


# -- target_plane ----------------------------------------------------------------------
def test_target_plane_from_the_job(tmp_path):
    point, normal = target_plane(write_job(tmp_path, plane_point_mm=(1.0, 2.0, 3.0), plane_normal=(0.0, 0.0, -4.0)))
    assert np.allclose(point, [1, 2, 3]) and np.allclose(normal, [0, 0, -1])


def test_target_plane_zero_normal_is_bad_input(tmp_path):
    with pytest.raises(BadInput, match="plane_normal"):
        target_plane(write_job(tmp_path, plane_normal=(0.0, 0.0, 0.0)))


def test_target_plane_from_a_fitted_plane(tmp_path):
    job = write_job(tmp_path, plane="fit")
    sq = np.array([[0, 0], [1, 0], [1, 1], [0, 1.0]])
    fitted = PlaneSurface(np.array([3.0, 601.0, -2.0]), np.array([0.0, 2.0, 0.0]), np.array([1.0, 0, 0]),
                          np.array([0, 0, 1.0]), Boundary(sq))
    point, normal = target_plane(job, fitted)
    assert np.allclose(point, [3, 601, -2]) and np.allclose(normal, [0, 1, 0])
    path = reach_path(job, point, normal, job.cell.base_xyz_mm)
    assert np.allclose(xyz(path)[:, 1], 601.0)  # the grid is projected onto the fitted wall


def test_target_plane_fit_needs_a_plane(tmp_path):
    job = write_job(tmp_path, plane="fit")
    with pytest.raises(BadInput, match="nothing"):
        target_plane(job, None)
    sphere = SpherePatch(np.zeros(3), 500.0, np.eye(3), Boundary(np.array([[0, 0], [1, 0], [1, 1.0]])))
    with pytest.raises(BadInput, match="SpherePatch"):
        target_plane(job, sphere)


# -- family table ----------------------------------------------------------------------
def family(signs, fixed, fixed_ok, opt, opt_ok, it):
    z = np.zeros((2, 7))
    return FamilyResult(signs, fixed, fixed_ok, opt, opt_ok, np.zeros(2), z, z, it)


FAMILIES = (family((1, -1, 1), 0.5, True, 0.4, True, 12),
            family((-1, 1, -1), float("nan"), False, float("nan"), False, 0),
            family((1, 1, 1), 12.34567, True, 11.5, False, 123))


def test_family_table_rows_and_values():
    text = family_table_text(ArmAngleResult(FAMILIES, 2, "fixed", np.pi / 4))
    lines = text.splitlines()
    assert text.endswith("\n") and len(lines) == 4
    assert lines[0].split() == ["family", "g1", "g2", "g3", "E_fixed_rad", "fixed_ok", "E_opt_rad", "opt_ok",
                                "sqp_it"]
    rows = [ln.split() for ln in lines[1:]]
    assert rows[0][:9] == ["1", "+1", "-1", "+1", "0.5000", "yes", "0.4000", "yes", "12"]
    assert rows[1][:9] == ["2", "-1", "+1", "-1", "nan", "no", "nan", "no", "0"]
    assert rows[2][:9] == ["3", "+1", "+1", "+1", "12.3457", "yes", "11.5000", "no", "123"]
    assert [("<-" in ln) for ln in lines[1:]] == [False, False, True]
    assert lines[3].endswith("<- kept (fixed)")


def test_family_table_without_a_kept_family():
    text = family_table_text(ArmAngleResult(FAMILIES[1:2], -1, "optimised", np.pi / 4))
    assert len(text.splitlines()) == 2 and "kept" not in text
