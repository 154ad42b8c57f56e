"""The placement package: batched closed-form IK, the screen, margins, the nearest shift, partial paths."""
import numpy as np
import pytest

from camtool.errors import BadInput, PlanInfeasible
from camtool.job import load_job
from camtool.placement.kinematics import ClosedForm
from camtool.placement.margins import reach_margins
from camtool.placement.partial import partial_path, partial_summary, reachable_stretches
from camtool.placement.screen import PathGeometry, ScreenSettings, move_path, placement_matrix, screen_batch
from camtool.placement.search import parse_vary, placed_job, placement_of
from camtool.placement.shift import nearest_feasible_shift
from camtool.robots import get_robot
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, plan_for_job, robot_for_job, surface_for_job, workpiece_for_job
from camtool.path.toolpath import Path, ZONE_CODE
from camtool.transforms import matrix_from_xyz_rpy

from conftest import SAMPLES

COARSE = ["workpiece.sample_points=20000", "raster.step_over_mm=40", "raster.pitch_mm=20"]
HIGH = ["cell.workpiece_xyz_mm=[1000,0,250]"]  # the sample patch 150 mm higher: out of reach


def _job(extra=()):
    return load_job(SAMPLES / "sphere.toml", COARSE + list(extra))


@pytest.fixture(scope="module")
def high():
    """The sample 150 mm higher on a coarse raster: job, robot, settings, workpiece, path."""
    job = _job(HIGH)
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    return job, robot, JobSettings.from_job(job, robot), wp, path_for_job(job, surface_for_job(job, wp))


@pytest.mark.parametrize("name", ["seed8", "sia20", "irb2400"])
def test_closed_form_solutions_reach_the_poses(name):
    robot = get_robot(name).with_placement(None, matrix_from_xyz_rpy([0, 0, 80], [0, 0, 0]))
    model = ClosedForm.for_robot(robot)
    L = robot.limits
    rng = np.random.default_rng(0)
    qs = L.lower + (L.upper - L.lower) * (0.05 + 0.9 * rng.random((160, robot.dof)))
    qs = qs[[robot.within_limits(q) for q in qs]][:40]  # configurations the controller takes (coupled J3)
    assert len(qs) == 40
    T = np.array([robot.fk_tcp(q) for q in qs])
    q, m, has = model.best(T)
    assert has.all() and np.isfinite(m).all() and (m >= 0).all()
    for qi, Ti in zip(q, T):
        assert robot.within_limits(qi)
        assert np.abs(robot.fk_tcp(qi) - Ti).max() < 1e-6
    ok, used, _ = model.bound(model.wrist_centres(T))
    assert ok.all()
    assert np.all(used <= model.reach_used_q(qs) + 1e-9)  # the bound's shoulder is the nearest one
    J = model.jacobian(qs[:3])
    assert np.allclose(J, [robot.jacobian(x, tcp=True) for x in qs[:3]], atol=1e-8)


def test_placement_matrix_and_job():
    D = placement_matrix((10, -20, 30, 90), [1000, 0, 100])
    assert np.allclose(D @ [1000, 0, 100, 1], [1010, -20, 130, 1])   # the pivot only translates
    assert np.allclose(D @ [1100, 0, 100, 1], [1010, 80, 130, 1])    # turned about world z
    job = _job()
    xyz, rpy = placement_of(job, (10, -20, 30, 90))
    assert xyz == [1010.0, -20.0, 130.0] and rpy == [0.0, 0.0, 90.0]
    pj = placed_job(job, (10, -20, 30, 90))
    T_old = matrix_from_xyz_rpy(job.cell.workpiece_xyz_mm, job.cell.workpiece_rpy_deg)
    T_new = matrix_from_xyz_rpy(pj.cell.workpiece_xyz_mm, pj.cell.workpiece_rpy_deg)
    assert np.allclose(T_new, D @ T_old)


def test_moving_the_path_equals_rastering_the_moved_job():
    """Translations commute with fit and raster: the screen may move the path instead of refitting."""
    job = _job()
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    off = (-60.0, 40.0, -30.0, 0.0)
    pj = placed_job(job, off)
    again = path_for_job(pj, surface_for_job(pj, workpiece_for_job(pj)))
    moved = move_path(path, placement_matrix(off, job.cell.workpiece_xyz_mm))
    assert len(again) == len(moved)
    assert np.abs(again.poses_mm - moved.poses_mm).max() < 1e-6


def test_screen_flags_the_high_patch_and_is_batch_independent(high):
    job, robot, st, _, path = high
    model = ClosedForm.for_robot(robot, path.free_spin)
    settings = ScreenSettings()
    geom = PathGeometry.build(path, model, robot, job.cell.workpiece_xyz_mm, settings)
    offs = [(0, 0, 0, 0), (-100, 0, -50, 0), (0, 0, -150, 0), (150, 0, 0, 0)]
    together = screen_batch(model, geom, offs, settings)
    alone = [screen_batch(model, geom, [o], settings)[0] for o in offs]
    assert [r.as_dict() for r in together] == [r.as_dict() for r in alone]
    user, moved, back, far = together
    assert not user.feasible and user.stage == "bound" and user.unreachable > 0 and user.reach_used > 1
    assert moved.feasible and moved.reach_used < 0.95 and moved.cost < np.inf
    assert back.feasible                                   # the shipped sample's own placement
    assert not far.feasible
    with pytest.raises(PlanInfeasible) as exc:
        plan_for_job(st, path, robot)
    assert len(exc.value.report["unreachable"]) > 0


def test_nearest_feasible_shift_plans(high):
    job, robot, st, wp, path = high
    shift = nearest_feasible_shift(job, st, robot, path)
    assert shift is not None and not shift["already_reachable"]
    assert 0 < shift["distance_mm"] < 150
    d = np.linalg.norm([shift["dx_mm"], shift["dy_mm"], shift["dz_mm"]])
    assert shift["distance_mm"] == pytest.approx(d, abs=1e-2)
    assert "cell.workpiece_xyz_mm" in shift["message"]
    moved = load_job(SAMPLES / "sphere.toml", COARSE + [f"cell.workpiece_xyz_mm={shift['workpiece_xyz_mm']}"])
    r2 = robot_for_job(moved)
    wp2 = workpiece_for_job(moved)
    p2 = path_for_job(moved, surface_for_job(moved, wp2))
    plan_for_job(JobSettings.from_job(moved, r2), p2, r2, wp2)   # raises if any pose is out of reach


def test_reach_margins_of_a_plan():
    job = _job()
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    path = path_for_job(job, surface_for_job(job, wp))
    jp = plan_for_job(JobSettings.from_job(job, robot), path, robot, wp)
    m = reach_margins(path, jp, robot)
    jl = m["joint_limit"]
    assert 0 <= jl["min_share"] <= 0.5 and jl["joint"] in robot.joint_names
    assert jl["min_share"] == min(jl["per_joint_min_share"].values())
    assert 50 < m["reach"]["max_used_pct"] <= 100 and m["reach"]["margin_pct"] == pytest.approx(
        100 - m["reach"]["max_used_pct"], abs=0.02)
    assert m["reach"]["max_reach_mm"] == pytest.approx(818.0)
    man = m["manipulability"]
    assert 0 < man["dexterity_min"] <= man["dexterity_median"] <= 1
    assert 0 < man["yoshikawa_min"] <= man["yoshikawa_median"]


def _toy_path():
    """Two segments: lead_in, 5 work, lead_out each, a self-motion zone between."""
    zone, seg = [], []
    for s in range(2):
        zone += [ZONE_CODE["lead_in"]] + [ZONE_CODE["work"]] * 5 + [ZONE_CODE["lead_out"]]
        seg += [s] * 7
        if s == 0:
            zone += [ZONE_CODE["self_motion"]] * 2
            seg += [0, 0]
    n = len(zone)
    poses = np.repeat(np.eye(4)[None], n, axis=0)
    poses[:, 0, 3] = np.arange(n)
    return Path(poses, np.array(seg), np.arange(n), np.array(zone))


def test_reachable_stretches_and_partial_path():
    path = _toy_path()
    # a cut end's work pose becomes the stretch's lead (#24: no work corner into the lift after a cut)
    assert reachable_stretches(path, [3, {"index": 12}], min_work_poses=2) == []
    st = reachable_stretches(path, [3, {"index": 12}], min_work_poses=1)
    assert [(s.first, s.last) for s in st] == [(0, 2), (4, 6), (9, 11), (13, 15)]
    assert [s.work_poses for s in st] == [1, 1, 1, 1]
    assert [(s.cut_in, s.cut_out) for s in st] == [(False, True), (True, False)] * 2
    assert [(s.first, s.last) for s in reachable_stretches(path, [3], min_work_poses=3)] == [(9, 15)]
    sub, idx = partial_path(path, st, [3, 12])
    assert list(idx) == [0, 1, 2, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 15]   # connector 7-8 kept
    assert len(set(sub.segment.tolist())) == 4
    z = dict(zip(idx.tolist(), sub.zone.tolist()))
    assert (z[2], z[4], z[11], z[13]) == (ZONE_CODE["lead_out"], ZONE_CODE["lead_in"]) * 2
    assert z[1] == z[5] == ZONE_CODE["work"]
    s = partial_summary(path, st)
    assert s["work_poses_kept"] == 4 and s["work_poses_total"] == 10 and s["segments_split"] == 2


def test_partial_path_of_the_high_patch_plans(high):
    job, robot, st, wp, path = high
    with pytest.raises(PlanInfeasible) as exc:
        plan_for_job(st, path, robot, wp)
    bad = exc.value.report["unreachable"]
    stretches = reachable_stretches(path, bad)
    sub, idx = partial_path(path, stretches, bad)
    assert not set(idx) & {u["index"] for u in bad}
    jp = plan_for_job(st, sub, robot, wp)
    assert jp.reached[jp.path_index >= 0].all()


@pytest.mark.parametrize("text", ["x=1:0", "q=0:1", "x=a:1", "x0:1", "yaw=-200:200", "z=nan:1"])
def test_parse_vary_rejects(text):
    with pytest.raises(BadInput):
        parse_vary(text)


def test_parse_vary():
    v = parse_vary("yaw=-30:15")
    assert (v.name, v.lower, v.upper, v.unit) == ("yaw", -30.0, 15.0, "deg")


def test_a_reach_hint_names_only_a_placement_that_plans(high, monkeypatch):
    """Issue #48: the placement a reach failure prints has been planned and timed there; one that does not plan
    is not printed: wider screen margins are tried, and if none plans the hint names no placement."""
    from camtool.run import reach_hint

    job, robot, st, wp, path = high
    shift = reach_hint.planned_shift(job, st, robot, path)
    assert shift["planned"] and "plans and times every pose (tried)" in shift["message"]
    assert f"cell.workpiece_xyz_mm = [{', '.join(f'{v:g}' for v in shift['workpiece_xyz_mm'])}]" in shift["message"]
    moved = reach_hint.placed(job, shift)
    assert reach_hint.why_not_planned(moved) is None and moved.cell.workpiece_xyz_mm == shift["workpiece_xyz_mm"]

    tried = []

    def fails_first(j):
        tried.append(list(j.cell.workpiece_xyz_mm))
        return "timing: run of surface rows 1..2: time law: the spline leaves the joint range" if len(tried) == 1 else None

    monkeypatch.setattr(reach_hint, "why_not_planned", fails_first)
    wider = reach_hint.planned_shift(job, st, robot, path)
    assert wider["planned"] and len(tried) == 2 and tried[0] != tried[1] and wider["workpiece_xyz_mm"] == tried[1]
    monkeypatch.setattr(reach_hint, "why_not_planned", lambda j: "does not plan")
    none = reach_hint.planned_shift(job, st, robot, path)
    assert not none["planned"] and "cell.workpiece_xyz_mm =" not in none["message"] and "camtool place" in none["message"]
