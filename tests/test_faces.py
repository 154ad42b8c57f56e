"""camtool.part.faces and `camtool faces JOB`: segmentation per job, selection, the picture, per-face raster keys."""
import json

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.part.faces import segment_faces, select_faces
from camtool.run.part_stages import face_surface, faces_settings
from camtool.job import load_job
from camtool.run.job_settings import JobSettings
from camtool.run.stages import path_for_job, surface_for_job, workpiece_for_job
from camtool.part.surface import FaceSet

from conftest import SAMPLES, run_camtool


def write_job(tmp_path, faces: str, extra: str = "", part: str = "pipe_half.stl"):
    job = tmp_path / "job.toml"
    job.write_text(f'[workpiece]\nfile = "{SAMPLES / part}"\nsample_points = 30000\n[faces]\n{faces}\n{extra}')
    return job


@pytest.fixture(scope="module")
def pipe(tmp_path_factory):
    job = load_job(write_job(tmp_path_factory.mktemp("pipe"), 'select = "all"'))
    wp = workpiece_for_job(job)
    return job, wp, segment_faces(faces_settings(job), wp)


def test_select_all_indices_model_largest_nearest(pipe):
    job, wp, seg = pipe
    assert [f.index for f in select_faces(seg, "all", wp)] == list(range(6))
    assert [f.index for f in select_faces(seg, [3, 1], wp)] == [1, 3]
    assert [f.model for f in select_faces(seg, "cylinder", wp)] == ["cylinder", "cylinder"]
    assert [f.index for f in select_faces(seg, {"largest": 2}, wp)] == [0, 1]
    inner = select_faces(seg, {"nearest_mm": [0.0, 0.0, 95.0]}, wp)  # just inside the bore's top
    assert len(inner) == 1 and inner[0].model == "cylinder" and inner[0].surface.concave
    end = select_faces(seg, {"nearest_mm": [160.0, 0.0, 110.0]}, wp)
    assert end[0].model == "plane" and abs(end[0].surface.normal[0]) > 0.999
    with pytest.raises(BadInput, match="selects no face"):
        select_faces(seg, "sphere", wp)
    with pytest.raises(BadInput, match="has 6 faces"):
        select_faces(seg, [9], wp)


def test_single_is_the_old_fit_and_a_selection_gives_that_faces_surface(tmp_path):
    job = load_job(write_job(tmp_path, 'select = [1]'))
    assert faces_settings(job).segmented and JobSettings.from_job(job).segmented
    s = surface_for_job(job, workpiece_for_job(job))
    assert s.model == "cylinder" and s.concave and abs(s.radius_mm - 100) < 0.5
    plain = load_job(write_job(tmp_path, "", "[fit]\nmodel = \"cylinder\"\n"))
    assert not faces_settings(plain).segmented and not JobSettings.from_job(plain).segmented
    cylinders = load_job(write_job(tmp_path, 'select = "cylinder"'))
    both = face_surface(cylinders, faces_settings(cylinders), workpiece_for_job(job))
    assert isinstance(both, FaceSet) and both.indices == (0, 1)  # two cylinders: one program for both
    assert [f.model for f in both.surfaces] == ["cylinder", "cylinder"]


def test_per_face_raster_keys_become_the_jobs(tmp_path):
    job = load_job(write_job(tmp_path, 'select = [0]\nraster = {"0" = {step_over_mm = 25.0, cylinder_rows = "along"}}'))
    assert job.raster.step_over_mm == 25.0 and job.raster.cylinder_rows == "along"
    path = path_for_job(job, surface_for_job(job, workpiece_for_job(job)))
    assert path.step_over_mm == 25.0
    with pytest.raises(BadInput, match="need faces.select"):
        load_job(write_job(tmp_path, 'select = "all"\nraster = {"0" = {step_over_mm = 5.0}}'))
    with pytest.raises(BadInput, match="not one of the selected"):
        load_job(write_job(tmp_path, 'select = [0]\nraster = {"2" = {step_over_mm = 5.0}}'))
    with pytest.raises(BadInput, match="step_over_mm"):
        load_job(write_job(tmp_path, 'select = [0]\nraster = {"0" = {step_over_mm = -5.0}}'))


@pytest.mark.parametrize("text", ['select = "cone"', "select = []", "select = [1, 1]", "select = {largest = 0}",
                                  "select = {nearest_mm = [1, 2]}", "select = {biggest = 2}", "select = 3.5"])
def test_bad_selections_are_one_line(tmp_path, text):
    with pytest.raises(BadInput, match="faces.select: expected"):
        load_job(write_job(tmp_path, text))


def test_cli_faces_json_and_png(tmp_path):
    job = write_job(tmp_path, 'select = "cylinder"')
    out = tmp_path / "out"
    r = run_camtool("faces", job, "--json", "-o", out)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert [f["model"] for f in d["faces"]] == ["cylinder", "cylinder", "plane", "plane", "plane", "plane"]
    first = d["faces"][0]
    for key in ("index", "model", "area_mm2", "axis", "radius_mm", "center_mm", "inliers"):
        assert key in first
    assert abs(first["radius_mm"] - 120) < 0.5 and abs(abs(first["axis"][0]) - 1) < 1e-4
    assert "normal" in d["faces"][2] and d["faces"][2]["radius_mm"] is None
    assert [f["selected"] for f in d["faces"]] == [True, True, False, False, False, False]
    png = out / "faces.png"
    assert d["image"] == str(png) and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    text = run_camtool("faces", job)
    assert text.returncode == 0 and "cylinder inside" in text.stdout and "* = selected" in text.stdout


def test_cli_faces_bad_input_is_one_line(tmp_path):
    r = run_camtool("faces", write_job(tmp_path, "select = [7]"))
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "has 6 faces" in r.stderr


def test_cylinder_job_end_to_end_passes_the_motion_check(tmp_path):
    """samples/pipe_half.toml as shipped: the outside cylinder is rastered, planned, checked and posted."""
    out = tmp_path / "out"
    r = run_camtool("run", SAMPLES / "pipe_half.toml", "-o", out)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "ok" and report["motion_check"]["ok"]
    assert (out / "PIPE.mod").is_file()
    # report.json and report.html show the part's faces, numbered as `camtool faces` numbers them
    faces = report["faces"]
    assert faces["select"] == [0] and [f["selected"] for f in faces["faces"]] == [True] + [False] * 5
    assert faces["faces"][0]["model"] == "cylinder" and "labels" not in faces
    page = (out / "report.html").read_text()
    assert "Faces of the part" in page and 'id="camtool-faces"' in page and "face 0: cylinder (worked)" in page
    raster = run_camtool("raster", SAMPLES / "pipe_half.toml", "--json")
    assert raster.returncode == 0 and json.loads(raster.stdout)["coverage"] >= 0.995


DOME_JOB = """
[workpiece]
file = "{stl}"
[faces]
select = [1]
[raster]
step_over_mm = 10.0
pitch_mm = 5.0
tool_x = "travel"
lead_path = "{lead_path}"
lead_auto = false
[robot]
name = "seed8"
[cell]
workpiece_xyz_mm = [750.0, 12.0, 440.0]
workpiece_rpy_deg = [0.0, -90.0, 0.0]
[tool]
tcp_xyz_mm = [0.0, 0.0, 150.0]
[planner]
method = "seed"
[timing]
method = "quintic"
[post]
formats = ["rapid"]
program_name = "DOME"
"""


def test_a_dome_on_a_cylinder_is_worked_with_its_leads_clear_of_the_cylinder(tmp_path):
    """The dome of samples/dome_cylinder.stl (a hemisphere on a cylinder of its radius, meeting it tangentially):
    its leads on the sphere continued past the rim dip into the cylinder (0.7-2.0 mm in every row's leads), and
    the motion check refuses that program; the run plans again with the leads lifted clear of the rows' tangents
    (raster.lead_path = "tangent"), says so, and that program passes."""
    job = tmp_path / "dome.toml"
    job.write_text(DOME_JOB.format(stl=(SAMPLES / "dome_cylinder.stl").as_posix(), lead_path="surface"))
    out = tmp_path / "out"
    r = run_camtool("run", job, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "in lead_" in r.stderr and 'planned again with the leads lifted' in r.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "ok" and report["motion_check"]["ok"]
    assert report["leads_retried"]["lead_path"] == "tangent" and "penetrated" in report["leads_retried"]["because"]
    assert report["motion_check"]["max_penetration_mm"] < 0.1
    assert [f["model"] for f in report["faces"]["faces"]] == ["cylinder", "sphere"]   # (its coverage: faces_coverage)


def test_every_face_of_a_scan_in_one_program_passes_the_motion_check(tmp_path):
    """samples/plate_chamfer_scan.toml as shipped: all nine faces of a noisy scan (sigma 0.1 mm) are segmented,
    covered to 99.5 % or more, and checked against the scan itself; the tolerance grows by 3 x the largest
    face's fit RMS (a job of several faces once had none and stopped there)."""
    out = tmp_path / "out"
    r = run_camtool("run", SAMPLES / "plate_chamfer_scan.toml", "-o", out)
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    assert report["status"] == "ok" and report["motion_check"]["ok"]
    worked = report["faces"]["worked"]
    assert len(worked) == 9 and min(w["coverage"] for w in worked) >= 0.995
    assert all(w["motion_check"]["failing_samples"] == {} or not any(w["motion_check"]["failing_samples"].values())
               for w in worked)


def test_fit_stage_file_of_a_face_resumes_the_raster(tmp_path):
    job = write_job(tmp_path, "select = [1]", '[raster]\nstep_over_mm = 30.0\npitch_mm = 15.0\n')
    out = tmp_path / "out"
    fit = run_camtool("fit", job, "-o", out, "--json")
    assert fit.returncode == 0, fit.stderr
    d = json.loads(fit.stdout)
    assert d["model"] == "cylinder" and d["concave"] and abs(d["radius_mm"] - 100) < 0.5 and "axis" in d
    resumed = run_camtool("raster", job, "--from", out / "surface.json", "--json")
    direct = run_camtool("raster", job, "--json")
    assert resumed.returncode == 0 and direct.returncode == 0
    assert json.loads(resumed.stdout) == json.loads(direct.stdout)


def test_cli_faces_of_a_bare_part_file_in_its_units(tmp_path):
    """`camtool faces PART` (a mesh, not a job file; issue #46: a new user's first command): the part's faces in
    its own frame, the same as a job's around it; a copy in metres with --units m gives the same faces in mm."""
    import trimesh

    metres = tmp_path / "pipe_half_m.stl"
    trimesh.load(SAMPLES / "pipe_half.stl", force="mesh").apply_scale(0.001).export(metres)
    job = run_camtool("faces", write_job(tmp_path, ""), "--json", "--set", "faces.select=all")
    assert job.returncode == 0, job.stderr
    want = json.loads(job.stdout)["faces"]
    for part, units in ((SAMPLES / "pipe_half.stl", "mm"), (metres, "m")):
        r = run_camtool("faces", part, "--units", units, "--json", "--set", "workpiece.sample_points=30000")
        assert r.returncode == 0 and r.stderr == "", r.stderr
        got = json.loads(r.stdout)["faces"]
        assert [f["model"] for f in got] == [f["model"] for f in want] == ["cylinder", "cylinder"] + ["plane"] * 4
        for g, w in zip(got, want):
            assert g["area_mm2"] == pytest.approx(w["area_mm2"], rel=0.01)
            assert np.allclose(g["center_mm"], w["center_mm"], atol=0.5)
