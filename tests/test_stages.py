"""Stage helpers shared by the tasks (camtool.run.stages): leads sized for the ramps, densified rows' zones."""
import numpy as np
import pytest

from camtool.job import load_job
from camtool.plan import plan_path
from camtool.plan.smooth import smooth_runs
from camtool.run.job_settings import JobSettings
from camtool.run.stages import (
    part_for_checks,
    path_for_job,
    plan_for_job,
    plan_with_sized_leads,
    robot_for_job,
    surface_for_job,
    workpiece_for_job,
)
from camtool.timing import lead_needed_mm
from camtool.path.toolpath import SURFACE_CODES, ZONE_CODE

from conftest import SAMPLES


def _job(*overrides):
    job = load_job(SAMPLES / "sphere.toml", list(overrides))
    robot = robot_for_job(job)
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    settings = JobSettings.from_job(job, robot)
    return settings, surface, path_for_job(job, surface), robot, part_for_checks(settings, wp, surface)


@pytest.fixture(scope="module")
def short_leads_job():
    """The sample with 10 mm leads: too short for the ramps to and from 100 mm/s on every row."""
    return _job("raster.lead_mm=10")


def test_leads_are_lengthened_to_what_the_ramps_need(short_leads_job):
    settings, surface, path, robot, part = short_leads_job
    sized_path, jp = plan_with_sized_leads(settings, surface, path, robot, part)
    leads = jp.events["leads"]
    assert leads["lead_mm_set"] == 10.0 and leads["lead_mm_used"] > 10.0
    assert leads["lead_mm_used"] >= leads["needed_mm"]
    # the new path is rastered with the longer lead; the work poses are the same
    assert len(sized_path) > len(path)
    assert np.allclose(sized_path.poses_mm[sized_path.is_work], path.poses_mm[path.is_work], atol=1e-6)
    after = lead_needed_mm(jp, sized_path, robot, settings.timing)
    for run in after["per_run"]:
        assert run["lead_in_needed_mm"] <= run["lead_in_mm"] + 1e-6
        assert run["lead_out_needed_mm"] <= run["lead_out_mm"] + 1e-6


def test_lead_sizing_makes_the_whole_plan_once(short_leads_job, monkeypatch):
    """Leads are sized on the planning kernel's plan; smoothing, lifts and densifying run once, on the path
    with the leads chosen (they used to run again for every longer lead)."""
    import camtool.run.stages as stages
    settings, surface, path, robot, part = short_leads_job
    kernel, smoothed = [], []
    monkeypatch.setattr(stages, "plan_path", lambda p, *a, **k: kernel.append(len(p)) or plan_path(p, *a, **k))
    monkeypatch.setattr(stages, "smooth_runs", lambda jp, p, *a, **k: smoothed.append(len(p)) or smooth_runs(jp, p, *a, **k))
    sized_path, jp = plan_with_sized_leads(settings, surface, path, robot, part)
    assert jp.events["leads"]["lead_mm_used"] > 10.0
    assert kernel == [len(path), len(sized_path)]     # the kernel for each lead tried
    assert smoothed == [len(sized_path)]              # the rest once, for the lead taken


def test_lead_auto_off_or_capped_keeps_the_set_lead(short_leads_job):
    settings, surface, path, robot, part = short_leads_job
    from dataclasses import replace
    off = replace(settings, raster=replace(settings.raster, lead_auto=False))
    same_path, jp = plan_with_sized_leads(off, surface, path, robot, part)
    assert same_path is path and "leads" not in jp.events
    capped = replace(settings, raster=replace(settings.raster, lead_max_mm=10.0))
    same_path, jp = plan_with_sized_leads(capped, surface, path, robot, part)
    assert same_path is path and jp.events["leads"]["capped"] and jp.events["leads"]["lead_mm_used"] == 10.0


def test_rows_densified_next_to_the_self_motion_zone_belong_to_it():
    """A row inserted on a step between a lead and the self-motion zone is a self-motion row: inside the
    run it would bend the run's spline off the surface (the feed dropped to 70 mm/s on the sample)."""
    settings, surface, path, robot, part = _job()
    jp = plan_for_job(settings, path, robot, part)
    inserted = np.flatnonzero(jp.path_index < 0)
    prev_path_row = np.maximum.accumulate(np.where(jp.path_index >= 0, np.arange(len(jp.q)), 0))
    # rows inserted on a step out of a lead-out: before the fix they were lead-out rows of the run
    n = len(jp.q)
    next_path_row = np.minimum.accumulate(np.where(jp.path_index >= 0, np.arange(n), n - 1)[::-1])[::-1]
    next_to_lead = inserted[(jp.zone[prev_path_row[inserted]] == ZONE_CODE["lead_out"])
                            & (jp.zone[next_path_row[inserted]] == ZONE_CODE["self_motion"])]
    assert len(next_to_lead) > 0
    assert np.all(jp.zone[next_to_lead] == ZONE_CODE["self_motion"])
    for r in inserted[np.isin(jp.zone[inserted], SURFACE_CODES)]:  # inserted surface rows lie inside a run
        after = r + 1
        while jp.path_index[after] < 0:
            after += 1
        assert jp.zone[prev_path_row[r]] in SURFACE_CODES and jp.zone[after] in SURFACE_CODES, r


def test_stage_log_times_each_stage_once():
    import time

    from camtool.run.stages import StageLog

    seen = []
    log = StageLog(on_stage=lambda name, value: (seen.append(name), time.sleep(0.05)))
    time.sleep(0.02)
    log.done("a", 1)                       # 0.02 s, not the listener's 0.05 s
    with log.clock("b"):
        time.sleep(0.03)
    log.done("b", 2)                       # b: the block, plus ~0 until done
    x = sum(range(200_000))                # CPU work goes to c
    log.done("c", x)
    assert seen == ["a", "b", "c"] and list(log.seconds) == ["a", "b", "c"]
    assert 0.02 <= log.seconds["a"] < 0.045
    assert 0.03 <= log.seconds["b"] < 0.055
    assert log.cpu_seconds["c"] > 0 and log.cpu_seconds["b"] < 0.02   # sleeping is no CPU


def test_a_cloud_checks_tolerance_grows_by_its_noisiest_faces_rms():
    """``motion_check``'s noise term: the fit's RMS of one surface, the largest face's of several, 0 unknown."""
    from camtool.run.stages import _fit_rms_mm
    from camtool.part.surface import Boundary, FaceSet, FitStats, PlaneSurface

    def face(rms):
        stats = None if rms is None else FitStats(1.0, rms, 3 * rms, 100, 100)
        return PlaneSurface(np.zeros(3), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                            Boundary(np.array([[0, 0], [1, 0], [1, 1.0]])), stats)

    assert _fit_rms_mm(face(0.1)) == 0.1 and _fit_rms_mm(face(None)) == 0.0
    assert _fit_rms_mm(FaceSet((face(0.1), face(0.25), face(None)), (0, 1, 2), ({}, {}, {}))) == 0.25


def test_the_spline_is_measured_against_a_scanned_meshs_noise_band_as_the_motion_check_measures_it():
    """A scanned mesh's spline depth allows the band the motion check allows its TCP (``scanned_mesh_band_mm``);
    a CAD mesh's and a cloud's allow none (0.05 mm against a scan's bumps split 830 steps of the bezier dac scan)."""
    from dataclasses import replace

    from camtool.part.workpiece import Workpiece
    from camtool.run.stages import _scanned_mesh_band, scanned_mesh_band_mm
    from test_roughness import _triangulated, sheet

    settings = _job()[0]
    noisy, smooth = sheet(0.05), sheet(0.0)
    faces = _triangulated(noisy)
    scan = Workpiece(noisy, np.tile([0.0, 0, 1], (len(noisy), 1)), faces, "scan.ply", "mm", (), noisy)
    cad = replace(scan, points_mm=smooth, vertices_mm=smooth, source="cad.ply")
    band = _scanned_mesh_band(settings, scan)
    assert band == scanned_mesh_band_mm(scan) and 0.05 < band < 0.2    # the 0.05 mm noise's own quantile
    assert _scanned_mesh_band(settings, cad) == 0.0
    assert _scanned_mesh_band(settings, replace(scan, faces=None, vertices_mm=None)) == 0.0
    told_cad = replace(settings, workpiece=replace(settings.workpiece, scan="no"))
    assert _scanned_mesh_band(told_cad, scan) == 0.0


def test_a_scans_free_form_axes_are_low_passed_as_a_cad_meshs_and_only_a_cad_meshs_triangles_averaged(monkeypatch):
    """One verdict (issue #46): ``freeform_surface`` judges once whether its face is a scan's (``from_scan``) and
    averages only a CAD mesh's triangles for its normals (``mesh_normals``: a scan's carry the sensor's noise);
    ``shaped_for_part`` low-passes every free-form face's tool orientations along its rows, a scanned mesh's too
    (its own axes wobble with its bumps; the noether panel scan passes so since path.turn_split takes a new pose
    over a hole onto the face, not the chord), and ``face_projector`` reads the face's verdict, judging nothing."""
    from dataclasses import replace

    import camtool.part.freeform as freeform
    import camtool.run.stages as stages
    from camtool.part.workpiece import Workpiece
    from camtool.path.raster import raster_path
    from camtool.settings import RasterSettings
    from test_roughness import _triangulated, sheet

    settings = _job()[0]
    noisy, smooth = sheet(0.05), sheet(0.0)
    faces = _triangulated(noisy)
    scan = Workpiece(noisy, np.tile([0.0, 0, 1], (len(noisy), 1)), faces, "scan.ply", "mm", (), noisy)
    cad = replace(scan, points_mm=smooth, vertices_mm=smooth, source="cad.ply")

    averaged, judged = [], []
    monkeypatch.setattr(freeform, "mesh_normals", lambda chart, *a: averaged.append(1) or chart)
    real = freeform.mesh_is_scan
    monkeypatch.setattr(freeform, "mesh_is_scan", lambda *a: judged.append(1) or real(*a))
    scanned = freeform.freeform_surface(scan, settings.fit)
    assert scanned.from_scan and not averaged and len(judged) == 1
    made = freeform.freeform_surface(cad, settings.fit)
    assert not made.from_scan and averaged and len(judged) == 2
    assert freeform.freeform_surface(replace(scan, faces=None, vertices_mm=None), settings.fit).from_scan  # a cloud
    assert not freeform.freeform_surface(replace(scan, scan="no"), settings.fit).from_scan     # the job's word
    assert freeform.freeform_surface(replace(cad, scan="yes"), settings.fit).from_scan
    assert freeform.freeform_surface(cad, settings.fit, part=scan).from_scan     # a face judged by the whole part

    monkeypatch.setattr(stages, "mesh_is_scan", lambda *a: pytest.fail("face_projector judged the mesh again"))
    assert stages.face_projector(scanned, scan) is None
    assert stages.face_projector(made, cad) == made.project_mm

    path = raster_path(scanned, RasterSettings.make(step_over_mm=15.0, pitch_mm=5.0, lead_mm=5.0))
    shaped, _ = stages.shaped_for_part(settings, scanned, path, None)
    assert len(shaped) == len(path)
    np.testing.assert_array_equal(shaped.poses_mm[:, :3, 3], path.poses_mm[:, :3, 3])   # the positions kept
    turned = np.degrees(np.arccos(np.clip(np.einsum("ki,ki->k", shaped.poses_mm[:, :3, 2], path.poses_mm[:, :3, 2]),
                                          -1.0, 1.0)))
    assert turned.max() > 0.01     # the scan's axes low-passed
