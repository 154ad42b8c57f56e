"""camtool.process.outputs end to end: `camtool run` with a [process] writes the map, its figures and the page."""
import json

import numpy as np

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
