"""camtool.process.outputs end to end: `camtool run` with a [process] writes the map, its figures and the page."""
import json
from pathlib import Path

import numpy as np
import pytest

from conftest import SAMPLES, run_camtool


def test_run_with_a_process_writes_the_map_beside_report_json(tmp_path):
    out = tmp_path / "out"
    r = run_camtool("run", SAMPLES / "irb2400_plate.toml", "-o", out, "--set", "process.kind=polish",
                    "--set", "process.profile=parabolic", "--set", "raster.step_over_mm=20",
                    "--set", "raster.pitch_mm=10")
    assert r.returncode == 0, r.stderr
    report = json.loads((out / "report.json").read_text())
    pm = report["process_map"]
    for key in ("mean", "pv", "rms", "uniformity_within_5pct", "uniformity_within_10pct", "edge_rolloff_width_mm",
                "uncovered_area_mm2", "units", "cpu_seconds"):
        assert key in pm
    assert pm["units"] == "um" and pm["mean"] > 0 and pm["method"] == "convolution"
    assert 0 <= pm["uniformity_within_5pct"] <= pm["uniformity_within_10pct"] <= 1
    d = np.load(out / "process_map.npz")
    assert d["values"].shape == (len(d["v"]), len(d["u"])) and str(d["units"]) == "um"
    assert np.isclose(float(np.sum(d["values"] * d["area_mm2"] * d["material"]) / np.sum(d["area_mm2"] * d["material"])),
                      pm["mean"], rtol=1e-4)
    assert (out / "plots" / "process_map.png").is_file()
    assert pm["file"] == str(out / "process_map.npz")   # the placed path, not the staging folder's
    page = (out / "report.html").read_text()
    assert 'id="camtool-process-map"' in page and "Verdict" in page and "Process uniformity" in page
    assert page.index("Verdict") < page.index("Every key of report.json")


def test_run_without_a_process_has_no_map(tmp_path):
    out = tmp_path / "out"
    r = run_camtool("run", SAMPLES / "irb2400_plate.toml", "-o", out, "--set", "raster.step_over_mm=25",
                    "--set", "raster.pitch_mm=10")
    assert r.returncode == 0, r.stderr
    assert "process_map" not in json.loads((out / "report.json").read_text())
    assert not (out / "process_map.npz").exists()
    # the cell branch's self-collision check (#24) gives every run collision-world pairs (link x link, tool),
    # so the verdict names the closest of them rather than "no cell obstacles"
    page = (out / "report.html").read_text()
    assert "Closest approach to the cell" in page and "pairs checked" in page


def saddle_block(file):
    """A watertight block 200 x 140 x 40 mm whose top is the saddle z = (x^2 - y^2) / 1000 (a free-form face)."""
    import trimesh

    from test_freeform import grid_mesh

    x, y = np.arange(-100, 100.01, 2.5), np.arange(-70, 70.01, 2.5)
    V, F = grid_mesh(x, y, lambda X, Y: (X ** 2 - Y ** 2) / 1000.0)
    nx, ny = len(x), len(y)
    B = V.copy()
    B[:, 2] = -40.0
    idx = np.arange(nx * ny).reshape(ny, nx)
    loop = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
    a, b, n = loop, np.roll(loop, -1), len(V)
    side = np.concatenate([np.stack([a, b + n, b], 1), np.stack([a, a + n, b + n], 1)])
    m = trimesh.Trimesh(np.vstack([V, B]), np.vstack([F, F[:, ::-1] + n, side]), process=True)
    assert m.is_watertight and m.is_winding_consistent and m.volume > 0
    m.export(file)


def test_a_free_form_face_and_a_plane_in_one_program_each_get_their_map(tmp_path):
    """faces.select: the block's saddle top (free-form, towards the robot) and its upper side (a plane), one
    program; the map of each on its own sites (the saddle's own mesh, the plane's grid), the figures of both."""
    saddle_block(tmp_path / "block.stl")
    job = (SAMPLES / "irb2400_plate.toml").read_text()
    job = job.replace('file = "plate_hole.stl"', 'file = "block.stl"').replace('[fit]\nmodel = "plane"\n', "")
    # faces 1 and 5 (camtool faces): the saddle top (27 800 mm2, towards the robot) and the side facing up
    job = job.replace("[raster]", "[faces]\nselect = [1, 5]\n\n[raster]")
    job = job.replace("step_over_mm = 10.0", "step_over_mm = 15.0")
    job += '\n[process]\nkind = "polish"\nprofile = "parabolic"\ndiameter_mm = 30.0\n'
    (tmp_path / "block.toml").write_text(job)
    out = tmp_path / "out"
    r = run_camtool("run", tmp_path / "block.toml", "-o", out, "--set", 'post.formats=["rapid"]')
    assert r.returncode == 0, r.stderr
    assert "(freeform): " in r.stdout and "(plane): " in r.stdout
    pm = json.loads((out / "report.json").read_text())["process_map"]
    faces = {f["model"]: f for f in pm["faces"]}
    assert faces["freeform"]["method"] == "mesh-direct" and faces["plane"]["method"] == "convolution"
    for f in faces.values():
        assert f["mean"] > 0 and f["uncovered_share"] < 0.01 and Path(f["file"]).is_file()
        assert Path(f["png"]).is_file()
    assert pm["worked_area_mm2"] == pytest.approx(sum(f["worked_area_mm2"] for f in faces.values()), abs=0.2)
    assert 27000 < faces["freeform"]["worked_area_mm2"] < 29000   # the saddle's 28 000 mm2 on the surface
    d = np.load(out / "process_map.npz")
    assert str(d["layout"]) == "faces" and len(d["values"]) == len(d["material"])
    page = (out / "report.html").read_text()
    section = page[page.index('id="camtool-process-map"'):]
    assert '"type":"mesh3d"' in section and '"type":"surface"' in section
