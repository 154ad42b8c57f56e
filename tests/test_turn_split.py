"""camtool.path.turn_split: a free-form face's work steps that turn the tool axis by more than 5 deg are cut into
equal pieces on the face (issue #46: "no turn of more than 5 deg between neighbouring work poses"). Closed forms: a
roll of radius R rastered across its axis at pitch p turns p / R a step; a step of angle a is cut into
ceil(a / 5 deg) pieces of a / n, each point on the roll."""
import math

import numpy as np
import pytest
import trimesh

from camtool.part.fit import fit_surface
from camtool.path.raster import raster_path
from camtool.path.toolpath import WORK, ZONE_CODE, Path
from camtool.path.turn_split import MAX_TURN_DEG, split_turns
from camtool.settings import RasterSettings
from test_freeform import FIT, grid_mesh, mesh_workpiece

R_MM = 60.0      # the roll's radius: a 10 mm pitch turns 9.55 deg (the noether panel's pocket rim: 5-10 deg)
PITCH_MM = 10.0


def roll_mesh():
    """A roll z = sqrt(R^2 - x^2), 100 mm across (+-56 deg) and 80 mm along its axis y, on a 1 mm grid."""
    return grid_mesh(np.linspace(-50, 50, 101), np.linspace(-40, 40, 41), lambda X, Y: np.sqrt(R_MM ** 2 - X * X))


@pytest.fixture(scope="module")
def roll():
    V, F = roll_mesh()
    wp, _ = mesh_workpiece(V, F)
    return wp, fit_surface(wp, FIT)


def work_turns_deg(path: Path) -> np.ndarray:
    """The tool axis's turn (deg) between neighbouring work poses of one segment."""
    z = np.asarray(path.poses_mm[:, :3, 2])
    w = path.is_work
    step = w[:-1] & w[1:] & (path.segment[1:] == path.segment[:-1])
    return np.degrees(np.arccos(np.clip(np.einsum("ki,ki->k", z[:-1], z[1:]), -1.0, 1.0)))[step]


def on_roll_mm(points: np.ndarray) -> np.ndarray:
    return np.abs(np.hypot(points[:, 0], points[:, 2]) - R_MM)


def onto_cylinder(points, along=None):
    """Points taken onto the cylinder of radius R_MM about y, radially (the exact face), or along the lines
    ``along`` (the nearest meeting either way)."""
    p = np.asarray(points, float).copy()
    if along is None:
        p[:, [0, 2]] *= (R_MM / np.hypot(p[:, 0], p[:, 2]))[:, None]
        return p
    d = np.asarray(along, float)
    a = d[:, 0] ** 2 + d[:, 2] ** 2
    b = 2 * (p[:, 0] * d[:, 0] + p[:, 2] * d[:, 2])
    c = p[:, 0] ** 2 + p[:, 2] ** 2 - R_MM ** 2
    root = np.sqrt(b * b - 4 * a * c)
    t = np.stack([(-b - root) / (2 * a), (-b + root) / (2 * a)])
    t = np.take_along_axis(t, np.argmin(np.abs(t), axis=0)[None], axis=0)[0]
    return p + t[:, None] * d


def pose_on_roll(angle_rad: float) -> np.ndarray:
    """A pose on the roll at angle_rad from its top, the tool axis into it, x along the row."""
    out = np.array([math.sin(angle_rad), 0.0, math.cos(angle_rad)])
    T = np.eye(4)
    T[:3, 1], T[:3, 2], T[:3, 3] = [0.0, 1.0, 0.0], -out, R_MM * out
    T[:3, 0] = np.cross(T[:3, 1], T[:3, 2])
    return T


def test_a_step_is_cut_into_the_fewest_equal_pieces_on_the_face():
    """A 30 mm step on the 60 mm roll turns 28.65 deg: six pieces of 4.77 deg (closed form), each point on the
    roll; the lead-in before it and a step of another face (its mask False) are left as they were."""
    a = 30.0 / R_MM
    poses = np.array([pose_on_roll(-0.2), pose_on_roll(0.0), pose_on_roll(a), pose_on_roll(a + 0.3)])
    zone = np.array([ZONE_CODE["lead_in"], WORK, WORK, WORK])
    path = Path(poses, np.zeros(4, int), np.array([0, 1, 2, 3]), zone, face=np.array([3, 3, 3, 5]),
                contour=np.zeros(4, bool))
    out, added = split_turns(path, [(path.face == 3, onto_cylinder)])
    n = math.ceil(math.degrees(a) / MAX_TURN_DEG)
    assert n == 6 and added == n - 1 and len(out) == len(path) + n - 1
    turns = work_turns_deg(out)
    np.testing.assert_allclose(turns[:n], math.degrees(a) / n, atol=1e-9)       # the cut step, evenly
    assert turns[n] == pytest.approx(math.degrees(0.3))                           # the other face's step: as it was
    np.testing.assert_allclose(on_roll_mm(out.poses_mm[:, :3, 3]), 0.0, atol=1e-9)
    np.testing.assert_array_equal(out.point, [0, 1, 2, 3, 4, 5, 6, 7, 8])        # work points numbered along
    np.testing.assert_array_equal(out.face, [3] * 8 + [5])
    assert out.zone[0] == ZONE_CODE["lead_in"] and np.array_equal(out.poses_mm[0], poses[0])
    assert np.array_equal(out.poses_mm[-1], poses[-1]) and np.array_equal(out.poses_mm[1], poses[1])


def test_a_path_that_turns_little_comes_back_as_it_was():
    poses = np.array([pose_on_roll(0.01 * k) for k in range(5)])
    path = Path(poses, np.zeros(5, int), np.arange(1, 6), np.full(5, WORK))
    out, added = split_turns(path, [(np.ones(5, bool), onto_cylinder)])
    assert out is path and added == 0
    big = Path(np.array([pose_on_roll(0.0), pose_on_roll(0.5)]), np.array([0, 1]), np.array([1, 1]),
               np.full(2, WORK))
    assert split_turns(big, [(np.ones(2, bool), onto_cylinder)])[0] is big   # two segments: no step between them


def test_a_free_form_roll_rastered_across_its_axis_turns_at_most_5_deg_between_work_poses(roll):
    """The raster of a free-form roll (a mesh of it) at a 10 mm pitch across its axis turns p / R = 9.55 deg a
    step (the panel scan's pocket rim turns 5-10 deg a step); cut on the face, every step turns at most 5 deg,
    half the raster's, and each new point lies on the roll as the raster's own do."""
    wp, surface = roll
    path = raster_path(surface, RasterSettings.make(step_over_mm=20.0, pitch_mm=PITCH_MM, lead_mm=5.0))
    raw = work_turns_deg(path)
    assert np.median(raw) == pytest.approx(math.degrees(PITCH_MM / R_MM), abs=0.15)
    out, added = split_turns(path, [(np.ones(len(path), bool), surface.project_mm)])
    turns = work_turns_deg(out)
    assert raw.max() > 9.0 and turns.max() <= MAX_TURN_DEG
    assert added == len(raw) and np.median(turns) == pytest.approx(np.median(raw) / 2, abs=0.05)
    assert on_roll_mm(out.poses_mm[out.is_work, :3, 3]).max() <= on_roll_mm(path.poses_mm[path.is_work, :3, 3]).max()


@pytest.fixture(scope="module")
def roll_job(tmp_path_factory):
    """A job on the roll (an STL, the IRB2400 in front of it), rows across its axis: (job, workpiece, surface)."""
    from camtool.job import load_job
    from camtool.run.stages import surface_for_job, workpiece_for_job

    d = tmp_path_factory.mktemp("roll")
    V, F = roll_mesh()
    trimesh.Trimesh(V, F, process=False).export(d / "roll.stl")
    (d / "roll.toml").write_text(
        '[workpiece]\nfile = "roll.stl"\nunits = "mm"\n\n[fit]\nmodel = "freeform"\n\n'
        f'[raster]\nstep_over_mm = 20.0\npitch_mm = {PITCH_MM}\nlead_mm = 5.0\nangle_deg = 90.0\n\n'
        '[robot]\nname = "irb2400"\n\n'
        '[cell]\nworkpiece_xyz_mm = [1000.0, 0.0, 900.0]\nworkpiece_rpy_deg = [0.0, -90.0, 0.0]\n\n'
        '[tool]\nname = "polisher"\ntcp_xyz_mm = [0.0, 0.0, 150.0]\n')
    job = load_job(d / "roll.toml")
    wp = workpiece_for_job(job)
    return job, wp, surface_for_job(job, wp)


def test_camtool_shapes_a_free_form_faces_path_with_the_split(roll_job):
    """``run.stages.path_for_job`` (what ``camtool run`` and ``camtool raster`` plan, after the axis tilt and the
    leads) cuts the roll's turning steps: neighbouring work poses turn at most 5 deg."""
    from camtool.run.stages import path_for_job

    job, wp, surface = roll_job
    raw = work_turns_deg(path_for_job(job, surface))          # no workpiece: the raster as it is
    turns = work_turns_deg(path_for_job(job, surface, wp))
    assert raw.max() > 9.0 and turns.max() <= MAX_TURN_DEG


def test_of_several_faces_only_the_free_form_ones_are_cut(roll_job):
    """A path over two faces (``FaceSet``), the roll's rows as face 4 (free-form) and again as face 1 (an analytic
    face): face 4's steps are cut to 5 deg, face 1's keep their 9.6 deg (an analytic face keeps its raster)."""
    from types import SimpleNamespace
    from camtool.part.surface import FaceSet
    from camtool.run.job_settings import JobSettings
    from camtool.run.stages import shaped_for_part

    job, _, surface = roll_job
    one = raster_path(surface, RasterSettings.from_section(job.raster))
    n = len(one)
    both = Path(np.concatenate([one.poses_mm, one.poses_mm]), np.r_[one.segment, one.segment + one.segment.max() + 1],
                np.r_[one.point, one.point], np.r_[one.zone, one.zone], face=np.r_[np.full(n, 4), np.full(n, 1)])
    faces = FaceSet((surface, SimpleNamespace(model="cylinder")), (4, 1), ({}, {}))
    out, _ = shaped_for_part(JobSettings.from_job(job), faces, both, None)
    on4, on1 = (Path(out.poses_mm[out.face == f], out.segment[out.face == f], out.point[out.face == f],
                     out.zone[out.face == f]) for f in (4, 1))
    assert work_turns_deg(on4).max() <= MAX_TURN_DEG
    assert len(on1) == n and work_turns_deg(on1).max() == pytest.approx(work_turns_deg(one).max())


def test_a_step_where_the_chart_has_no_face_under_it_is_cut_onto_the_face_along_the_tool_axes():
    """Issue #46, the ship hull's bilge: where the face stands steep to its chart plane the chart holds no face
    under a chord point (here past 60 deg from the top of the roll, along z: NaN) and a new pose stayed on the
    chord, inside the part by its sag (the hull: 0.45 mm). Along its own tool axis it meets the face: a 30 mm
    step from 60 deg on the 60 mm roll is cut into six, every point on the roll (closed form)."""
    def chart_blind(points, along=None):
        onto = onto_cylinder(points, along)
        if along is None:
            onto[np.abs(np.asarray(points)[:, 0]) > R_MM * math.sin(math.radians(60.0))] = np.nan
        return onto

    a0, a = math.radians(60.0), 30.0 / R_MM
    poses = np.array([pose_on_roll(a0), pose_on_roll(a0 + a)])
    path = Path(poses, np.zeros(2, int), np.array([1, 2]), np.full(2, WORK))
    out, added = split_turns(path, [(np.ones(2, bool), chart_blind)])
    assert added == 5
    np.testing.assert_allclose(on_roll_mm(out.poses_mm[:, :3, 3]), 0.0, atol=1e-9)


def test_a_step_across_a_hole_is_cut_onto_the_face_continued_over_it_not_left_on_the_chord():
    """Issue #46, the noether panel scan at its placement: a row's 10 mm step crossed a 4.5 mm hole and its new pose,
    with no face under it, stayed on the chord, 0.66 mm above the hole's rim (the motion check allows 0.6). A 20 mm
    step over a 12 mm hole at the top of the 60 mm roll turns 19.1 deg: cut into four, the three new points (all
    over the hole) lie on the roll within the face's height field continued over it (< 0.25 mm); on the chord they
    would be 0.62-0.83 mm off it (closed form: R (1 - cos 9.55 deg) = 0.83 mm at the middle)."""
    V, F = roll_mesh()
    wp, _ = mesh_workpiece(V, F, keep=lambda c: np.hypot(c[:, 0], c[:, 1]) > 6.0)
    surface = fit_surface(wp, FIT)
    a = 20.0 / R_MM
    path = Path(np.array([pose_on_roll(-a / 2), pose_on_roll(a / 2)]), np.zeros(2, int), np.array([1, 2]),
                np.full(2, WORK))
    new = split_turns(path, [(np.ones(2, bool), surface.project_mm)])[0].poses_mm[1:-1, :3, 3]
    assert len(new) == 3 and np.abs(new[:, 0]).max() < 6.0                    # all three over the hole
    assert not np.isfinite(surface.project_mm(new)).all(axis=1).any()         # no face under any of them
    assert R_MM * (1 - math.cos(a / 2)) == pytest.approx(0.83, abs=0.005)
    assert on_roll_mm(new).max() < 0.25
