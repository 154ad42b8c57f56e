"""End to end (#24): the cell samples plan around their obstacles, and the issue's refusals plan.

Each test is one full run of the seed job (a 615 s program). The two partial-job cases of the issue
(the sample 150 mm higher, and 100 mm farther, with --allow-partial) run when CAMTOOL_SLOW=1.
"""
import json
import os

import pytest

from conftest import SAMPLES, run_camtool

slow = pytest.mark.skipif(os.environ.get("CAMTOOL_SLOW") != "1", reason="a full partial-job run; CAMTOOL_SLOW=1")


def _run(tmp_path, job, *args):
    r = run_camtool("run", job, "-o", tmp_path, "-q", *args)
    assert r.returncode == 0, r.stderr
    return json.loads((tmp_path / "report.json").read_text())


def _pairs_clear(report):
    mc = report["motion_check"]
    clearance = mc["cell"]["clearance_mm"]
    assert mc["cell_pairs"] and all(p["min_distance_mm"] >= clearance for p in mc["cell_pairs"])
    return {(p["a"], p["b"]): p for p in mc["cell_pairs"]}


def test_reconfiguration_is_routed_around_the_block(tmp_path):
    report = _run(tmp_path, SAMPLES / "cell_ceiling.toml")
    assert report["status"] == "ok"
    assert report["lifted_connectors"][0]["segment"] == 1 and report["lifted_connectors"][0]["rrt"] is True
    pairs = _pairs_clear(report)
    block = [p for (a, b), p in pairs.items() if b == "block"]
    assert len(block) == 5 and min(p["min_distance_mm"] for p in block) < 50.0   # it passes close by
    assert pairs[("j6-j7", "block")]["at"]["zone"] in ("self_motion", "approach", "depart", "work", "lead_in",
                                                       "lead_out", "retract")
    html = (tmp_path / "report.html").read_text()
    assert "obstacle block" in html


def test_sample_at_950_0_250_plans(tmp_path):
    """Refused by the first capsule model: 'at 25 mm above the surface the arm still touches the part'."""
    report = _run(tmp_path, SAMPLES / "sphere.toml", "--set", "cell.workpiece_xyz_mm=[950,0,250]")
    assert report["status"] == "ok" and report["motion_check"]["ok"] is True
    lifts = [c["lift_mm"] for c in report["lifted_connectors"]]
    assert lifts and lifts[0] == 100.0 and all(0 < h <= 100.0 for h in lifts)
    # the leads are sized on the planning kernel's plan: 42 mm, long enough on the whole plan (measured on
    # the whole plan first, a 51 mm lead could not be lifted at the edge of reach and 20 mm was kept, short)
    leads = report["leads"]
    assert leads["lead_mm_used"] > leads["lead_mm_set"] and leads["lead_mm_used"] >= leads["needed_mm"]
    _pairs_clear(report)


@slow
def test_sample_150_mm_higher_plans_as_a_partial_job(tmp_path):
    report = _run(tmp_path, SAMPLES / "sphere.toml", "--set", "cell.workpiece_xyz_mm=[1000,0,250]",
                  "--allow-partial")
    assert report["status"] == "ok" and report["partial"]["work_kept_pct"] > 99.0
    assert all(s["max_deviation_mm"] <= 0.1 for s in report["programs_simulated"].values())


@slow
def test_sample_100_mm_farther_partial_job_passes_the_simulator(tmp_path):
    report = _run(tmp_path, SAMPLES / "sphere.toml", "--set", "cell.workpiece_xyz_mm=[1100,0,100]",
                  "--allow-partial")
    assert report["status"] == "ok" and report["partial"]["work_kept_pct"] > 99.0
    assert all(s["max_deviation_mm"] <= 0.1 for s in report["programs_simulated"].values())


def test_coarse_raster_passes_its_own_check(tmp_path):
    """Refused by the check: 'part penetrated by 0.101 mm ... in lead_in' (chord sag at 20 mm pitch)."""
    report = _run(tmp_path, SAMPLES / "sphere.toml", "--set", "raster.step_over_mm=40", "--set", "raster.pitch_mm=20")
    mc = report["motion_check"]
    assert report["status"] == "ok" and mc["ok"] is True
    assert mc["work_deviation_mm"] <= 0.1 and mc["max_penetration_mm"] <= 0.1
