"""camtool.part.step: a STEP part's B-rep faces read exactly (OCP), its mesh, and its faces in a job."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.part.faces import segment_faces
from camtool.run.part_stages import faces_settings
from camtool.job import load_job
from camtool.run.stages import workpiece_for_job
from camtool.part.step import read_step_faces, step_mesh
from camtool.part.workpiece import load_workpiece

from conftest import SAMPLES

STEP = SAMPLES / "pipe_half.step"


def test_faces_types_parameters_and_sides():
    faces = read_step_faces(STEP)
    assert sorted(f.model for f in faces) == ["cylinder", "cylinder", "plane", "plane", "plane", "plane"]
    cyl = sorted((f for f in faces if f.model == "cylinder"), key=lambda f: f.params[2])
    (c0, a0, r0, concave0), (c1, a1, r1, concave1) = cyl[0].params, cyl[1].params
    assert r0 == 100.0 and concave0 and r1 == 120.0 and not concave1
    assert np.allclose(np.abs(a0), [1, 0, 0]) and np.allclose(c0[1:], 0)
    planes = sorted(tuple(np.round(f.params[0], 9) + 0.0) + (round(f.params[1], 6) + 0.0,)
                    for f in faces if f.model == "plane")
    assert planes == [(-1.0, 0.0, 0.0, 150.0), (0.0, 0.0, -1.0, 0.0), (0.0, 0.0, -1.0, 0.0), (1.0, 0.0, 0.0, 150.0)]
    for f in faces:  # triangles face out of the material
        tri = f.vertices_mm[f.triangles]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        mid = tri.mean(axis=1)
        if f.model == "plane":
            assert np.all(n @ f.params[0] > 0)
        else:
            c, a, r, concave = f.params
            radial = (mid - c) - ((mid - c) @ a)[:, None] * a
            assert np.all(np.einsum("ij,ij->i", n, radial) * (-1 if concave else 1) > 0)


def test_mesh_loads_as_a_workpiece():
    verts, tris, owner = step_mesh(STEP)
    assert len(tris) == len(owner) and owner.max() == 5
    wp = load_workpiece(STEP, sample_points=5000)
    assert wp.faces is not None and wp.n_points == 5000
    r = np.hypot(wp.points_mm[:, 1], wp.points_mm[:, 2])
    assert r.min() > 99.9 and r.max() < 120.01


def test_job_faces_are_the_brep_faces_placed(tmp_path):
    job = tmp_path / "job.toml"
    job.write_text(f'[workpiece]\nfile = "{STEP}"\nsample_points = 20000\n[faces]\nselect = [0]\n'
                   '[cell]\nworkpiece_xyz_mm = [600.0, 0.0, 300.0]\nworkpiece_rpy_deg = [0.0, -90.0, 0.0]\n')
    j = load_job(job)
    seg = segment_faces(faces_settings(j), workpiece_for_job(j))
    assert [f.model for f in seg.faces][:2] == ["cylinder", "cylinder"] and len(seg.faces) == 6
    outer = seg.faces[0].surface
    assert outer.radius_mm == 120.0 and not outer.concave and np.allclose(outer.axis, [0, 0, 1])
    d = outer.center_mm - [600.0, 0, 300.0]
    assert np.linalg.norm(d - (d @ outer.axis) * outer.axis) < 1e-9


def test_not_a_step_file_is_bad_input(tmp_path):
    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21;\nthis is not a part\n")
    with pytest.raises(BadInput, match="not a readable STEP file"):
        load_workpiece(bad)


def test_opencascade_messages_stay_off_stdout(tmp_path):
    from conftest import run_camtool

    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21;\nHEADER;\nthis is junk\n")
    r = run_camtool("fit", bad, "--json")
    assert r.returncode == 2 and r.stdout == "" and len(r.stderr.strip().splitlines()) == 1


def test_a_boss_all_round_keeps_its_outline_within_one_turn(tmp_path):
    """A cylindrical boss (R 20, 30 high) on a box, as a STEP solid: its face goes all round its axis, and the
    face's own points continue across its seam, so a vertex moved out past the seam is put back where its
    move crosses it. The outline is the exact rectangle u = -pi..pi, z = 40..70 (it reached u = -4.7 rad
    and 5 mm over the top, an area of 4308 mm2 for 3770)."""
    import contextlib
    import io
    import math

    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    from camtool.part.faces import step_segmentation
    from camtool.part.segment import SegmentSettings

    box = BRepPrimAPI_MakeBox(gp_Pnt(-100, -60, 0), 200, 120, 40).Shape()
    boss = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(40, 0, 40), gp_Dir(0, 0, 1)), 20.0, 30.0).Shape()
    file = tmp_path / "boss.step"
    writer = STEPControl_Writer()
    with contextlib.redirect_stdout(io.StringIO()):
        writer.Transfer(BRepAlgoAPI_Fuse(box, boss).Shape(), STEPControl_AsIs)
        writer.Write(str(file))
    seg = step_segmentation(file, load_workpiece(file), np.eye(4), SegmentSettings())
    cyl = [f for f in seg.faces if f.model == "cylinder"]
    assert len(cyl) == 1 and [f.model for f in seg.faces].count("plane") == 7
    s = cyl[0].surface
    lo, hi = s.boundary.bounds()
    assert np.allclose([lo[0], hi[0]], [-math.pi, math.pi], atol=1e-6)
    z = s.point_mm(np.zeros(2), np.array([lo[1], hi[1]]))[:, 2]
    assert np.allclose(z, [40.0, 70.0], atol=0.05)
    assert cyl[0].area_mm2 == pytest.approx(2 * math.pi * 20 * 30, rel=0.005)


READ_AHEAD = """
import sys
import numpy as np
from pathlib import Path
from camtool.part import step
path = Path(sys.argv[1])
step.read_ahead(path)
forked = "child" in step._AHEAD and "OCP" not in sys.modules
ahead = step.read_step_faces(path)
here = step._read_step_faces(path)
same = len(ahead) == len(here) and all(
    a.model == b.model and np.array_equal(a.vertices_mm, b.vertices_mm) and np.array_equal(a.triangles, b.triangles)
    and all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(a.params, b.params))
    for a, b in zip(ahead, here))
print(forked, same, len(ahead))
"""


def test_a_part_read_ahead_gives_the_faces_read_here():
    """``read_ahead`` reads and tessellates in a forked child (a fresh process: OpenCASCADE not imported yet);
    ``read_step_faces`` takes the very same faces as a read in the process itself gives."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", READ_AHEAD, str(STEP)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and out.stdout.split() == ["True", "True", "6"], out.stderr[-2000:]


def test_no_read_ahead_once_opencascade_meshed_here(tmp_path):
    """A child forked after OpenCASCADE's thread pool ran would wait forever: once OCP is imported, the file is
    read in this process."""
    import shutil

    from camtool.part import step as step_module

    read_step_faces(STEP)   # (OpenCASCADE imported and used here)
    copy = shutil.copy(STEP, tmp_path / "pipe.step")
    step_module.read_ahead(copy)
    assert "child" not in step_module._AHEAD
    assert len(read_step_faces(copy)) == 6


def test_a_bad_part_read_ahead_is_one_line(tmp_path):
    """What the child raises is raised here: the same BadInput line, exit 2, no traceback."""
    import subprocess
    import sys

    (tmp_path / "bad.step").write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n")
    job = (SAMPLES / "pipe_half_step.toml").read_text().replace('file = "pipe_half.step"', 'file = "bad.step"')
    (tmp_path / "job.toml").write_text(job)
    out = subprocess.run([sys.executable, "-c", "from camtool.cli import main; main()", "faces",
                          str(tmp_path / "job.toml")], capture_output=True, text=True, timeout=120)
    assert out.returncode == 2 and out.stdout == ""
    assert out.stderr.strip().splitlines() == [
        f"camtool: error: {tmp_path / 'bad.step'}: not a readable STEP file (OpenCASCADE could not transfer it); "
        "export it again"]
