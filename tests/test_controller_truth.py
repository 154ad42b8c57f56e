"""Programs read as the controller would, through the ROS-Industrial descriptions and drivers'
conventions (tests/controller_reader.py, independent of camtool's readers and simulator): every
target of the irb2400 and sia20 samples (small grids) on the planned path within post.path_tol_mm,
confdata / RCONF agreeing with the planned configuration's controller axes, MoveAbsJ and MoveL
agreeing where they meet, no target beyond the controller's limits, no pulse without factors."""
import json

import numpy as np
import pytest

from camtool.robots import get_robot

from conftest import SAMPLES, run_camtool
from controller_reader import check_program, plan_from_csv, rapid_tool, read_jbi, read_rapid

PATH_TOL_MM, ORI_TOL_DEG = 0.1, 0.1


@pytest.fixture(scope="module")
def irb_plate(tmp_path_factory):
    out = tmp_path_factory.mktemp("irb")
    r = run_camtool("run", SAMPLES / "irb2400_plate.toml", "-o", out, "--set", "raster.step_over_mm=60",
                    "--set", "raster.pitch_mm=10")
    assert r.returncode == 0, r.stderr
    return out


@pytest.fixture(scope="module")
def sia_wall(tmp_path_factory):
    out = tmp_path_factory.mktemp("sia")
    r = run_camtool("run", SAMPLES / "sia20_wall.toml", "-o", out, "--set", "task.grid_columns=3",
                    "--set", "task.grid_rows=2", "--set", "task.start_mm=[0, 600, 800]",
                    "--set", 'post.formats=["inform", "csv"]')
    assert r.returncode == 0, r.stderr
    return out


def test_irb2400_rapid_through_the_linkage_and_tool0(irb_plate):
    mod = irb_plate / "PLATE2400.mod"
    tool = rapid_tool(mod)
    q, T = plan_from_csv(irb_plate / "PLATE2400.csv", get_robot("irb2400").with_placement(tool_T_mm=tool))
    targets = read_rapid(mod)
    truth = check_program("irb2400", targets, q, T, tool)
    assert truth.targets > 20 and truth.switches >= 2
    assert truth.max_pos_mm <= PATH_TOL_MM and truth.max_ori_deg <= ORI_TOL_DEG, truth
    assert truth.conf_checked > 10 and truth.conf_mismatch == 0 and truth.switch_conf_mismatch == 0, truth
    assert truth.beyond_limits == 0
    # MoveAbsJ states the coupled axis 3: rax_3 = j2 + j3 of the plan
    j = next(t for t in targets if t.kind == "J")
    assert abs(j.joints_deg[2] - np.degrees(q[0, 1] + q[0, 2])) < 1e-3
    text = mod.read_text()
    assert "! Conventions: irb2400: manufacturer robot" in text and "rax_3 = j2 + j3" in text
    report = json.loads((irb_plate / "report.json").read_text())
    assert "manufacturer" in json.dumps(report)


def test_sia20_jbi_in_the_robot_frame_with_rconf_and_no_pulses(sia_wall):
    jbi = sia_wall / "SIAWALL.JBI"
    text = jbi.read_text()
    assert "///POSTYPE PULSE" not in text and "///RECTAN" in text      # no pulse factors: no pulses
    q, T = plan_from_csv(sia_wall / "SIAWALL.csv", get_robot("sia20"))
    truth = check_program("sia20", read_jbi(jbi), q, T, np.eye(4))
    assert truth.targets > 6
    assert truth.max_ori_deg <= ORI_TOL_DEG, truth
    assert truth.conf_checked == truth.targets and truth.conf_mismatch == 0, truth
    assert truth.max_extra_deg < 1e-3 and truth.beyond_limits == 0, truth
    assert "'MANUFACTURER ROBOT SIA20" in text and "'AXES S L U R B T E" in text


def test_sia20_jbi_targets_on_the_planned_path_within_the_tolerance(sia_wall):
    jbi = sia_wall / "SIAWALL.JBI"
    q, T = plan_from_csv(sia_wall / "SIAWALL.csv", get_robot("sia20"))
    truth = check_program("sia20", read_jbi(jbi), q, T, np.eye(4))
    assert truth.max_pos_mm <= PATH_TOL_MM, truth


def test_pulses_need_every_factor(tmp_path):
    """A profile with some pulse factors but not all: one line naming the missing key, no program."""
    prof = (SAMPLES.parent / "camtool" / "program" / "profile_data" / "sia20_inform.toml").read_text()
    prof = prof.replace('s = { axis = "RB1:1", sign = 1, offset = 0.0, unit = "deg", max_speed = 130.0 }',
                        's = { axis = "RB1:1", sign = 1, offset = 0.0, unit = "deg", pulses = 1000.0, max_speed = 130.0 }')
    (tmp_path / "p.toml").write_text(prof)
    job = (SAMPLES / "sia20_wall.toml").read_text().replace('[post]', '[post]\nprofiles = { inform = "p.toml" }')
    job = job.replace('file = "wall.ply"', f'file = "{SAMPLES / "wall.ply"}"')
    (tmp_path / "j.toml").write_text(job)
    r = run_camtool("run", tmp_path / "j.toml", "-o", tmp_path / "o", "--set", "task.grid_columns=2",
                    "--set", "task.grid_rows=2", "--set", "task.start_mm=[0, 600, 800]")
    assert r.returncode == 2 and "axes.l.pulses: missing" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not list((tmp_path / "o").glob("*.JBI")) if (tmp_path / "o").exists() else True
