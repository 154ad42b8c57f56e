"""KRL and LS programs read as the KUKA and FANUC controllers would (issue #47), through the
ROS-Industrial descriptions and the drivers' conventions (tests/controller_reader_kf.py,
independent of camtool's writers, readers and simulator): every target of the kr16 and m20ia
samples (coarse rasters) within 0.1 mm and 0.1 deg of the planned TCP, no target beyond the
controller's limits (FANUC: the pendant's J3 and the serial joint_3 both), joint and Cartesian
moves on one configuration where they meet."""
import json

import numpy as np
import pytest

from camtool.robots import get_robot
from camtool.transforms import matrix_from_xyz_rpy

from conftest import SAMPLES, run_camtool
from controller_reader import plan_from_csv
from controller_reader_kf import check_program, read_krl, read_ls

PATH_TOL_MM, ORI_TOL_DEG = 0.1, 0.1


@pytest.fixture(scope="module")
def kr16_sphere(tmp_path_factory):
    out = tmp_path_factory.mktemp("kr16")
    r = run_camtool("run", SAMPLES / "kr16_sphere.toml", "-o", out, "--set", "raster.step_over_mm=120")
    assert r.returncode == 0, r.stderr
    return out


@pytest.fixture(scope="module")
def m20ia_plate(tmp_path_factory):
    out = tmp_path_factory.mktemp("m20ia")
    r = run_camtool("run", SAMPLES / "fanuc_plate.toml", "-o", out, "--set", "raster.step_over_mm=60")
    assert r.returncode == 0, r.stderr
    return out


def test_kr16_krl_through_the_urdf_and_kuka_s_frames(kr16_sphere):
    targets, tool = read_krl(kr16_sphere / "KR16SPH.src")
    assert np.allclose(tool, matrix_from_xyz_rpy([106.066, 0.0, 106.066], [0.0, 45.0, 0.0]), atol=1e-3)
    q, T = plan_from_csv(kr16_sphere / "KR16SPH.csv", get_robot("kr16").with_placement(tool_T_mm=tool))
    truth = check_program("kr16", targets, q, T, tool)
    assert truth.targets > 20 and truth.switches >= 4
    assert truth.max_pos_mm <= PATH_TOL_MM and truth.max_ori_deg <= ORI_TOL_DEG, truth
    assert truth.beyond_limits == 0 and truth.beyond_serial == 0 and truth.switch_mismatch == 0, truth
    kinds = {t.kind for t in targets}
    assert kinds == {"J", "L", "C"}   # PTP off the surface, LIN and CIRC on it
    report = json.loads((kr16_sphere / "report.json").read_text())
    sim = report["programs_simulated"]["krl"]
    assert sim["max_deviation_mm"] <= PATH_TOL_MM and sim["exact_stops_on_surface"] == 0 and sim["cell"]["collisions"] == 0


def test_m20ia_ls_through_the_urdf_and_the_j23_linkage(m20ia_plate):
    targets, tool = read_ls(m20ia_plate / "M20PLATE.LS")
    assert np.allclose(tool, matrix_from_xyz_rpy([0.0, 0.0, 120.0], [0.0, 0.0, 0.0]), atol=1e-3)
    q, T = plan_from_csv(m20ia_plate / "M20PLATE.csv", get_robot("m20ia").with_placement(tool_T_mm=tool))
    truth = check_program("m20ia", targets, q, T, tool)
    assert truth.targets > 20 and truth.switches >= 4
    assert truth.max_pos_mm <= PATH_TOL_MM and truth.max_ori_deg <= ORI_TOL_DEG, truth
    assert truth.beyond_limits == 0 and truth.beyond_serial == 0 and truth.switch_mismatch == 0, truth
    # the pendant's J3 is j3 - j2 of the plan: read without the linkage, the TCP would be metres off
    from controller_reader_kf import Urdf, URDFS
    urdf = Urdf(URDFS["m20ia"])
    j = targets[0].joints_deg
    wrong = urdf.frame(np.radians(j), "tool0") @ tool
    right = urdf.frame(np.radians(j + np.array([0, 0, j[1], 0, 0, 0])), "tool0") @ tool
    assert np.linalg.norm(wrong[:3, 3] - right[:3, 3]) > 50.0
    report = json.loads((m20ia_plate / "report.json").read_text())
    sim = report["programs_simulated"]["fanuc"]
    assert sim["max_deviation_mm"] <= PATH_TOL_MM and sim["cell"]["collisions"] == 0
    assert any(p["b"] == "fixture" for p in report["motion_check"]["cell_pairs"])


def test_check_and_the_simulator_read_both(kr16_sphere, m20ia_plate):
    for f, job in ((kr16_sphere / "KR16SPH.src", "kr16_sphere.toml"), (m20ia_plate / "M20PLATE.LS", "fanuc_plate.toml")):
        r = run_camtool("check", f, "--job", SAMPLES / job, "--simulate", "--json")
        assert r.returncode == 0, r.stdout + r.stderr
        out = json.loads(r.stdout)
        assert out["ok"] and out["findings"] == [] and out["simulation"]["rows"] > 2
