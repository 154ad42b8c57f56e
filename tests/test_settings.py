"""Settings objects: built once from the job, units converted in one place, defaults from the schema."""
import math

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.job import SCHEMA, load_job
from camtool.robots import get_robot
from camtool.run.job_settings import JobSettings, home_q
from camtool.settings import FitSettings, PlannerSettings, PostSettings, RasterSettings, TimingSettings

from conftest import SAMPLES


def test_defaults_come_from_the_schema():
    r = RasterSettings.make()
    assert r.step_over_mm == SCHEMA["raster"]["step_over_mm"].default
    assert r.angle_rad == math.radians(SCHEMA["raster"]["angle_deg"].default)
    assert FitSettings.make().threshold_mm == SCHEMA["fit"]["threshold_mm"].default
    t = TimingSettings.make(check_dt_ms=2.0)
    assert t.check_dt_s == pytest.approx(0.002)
    assert PostSettings.make(min_move_ms=20).min_move_s == pytest.approx(0.02)


def test_angles_become_radians():
    p = PlannerSettings.make(jump_threshold_deg=30, orientation_tol_deg=1e-3, clamp_buffer_deg=5)
    assert p.jump_threshold_rad == pytest.approx(math.radians(30))
    assert p.orientation_tol_rad == pytest.approx(math.radians(1e-3))
    assert p.clamp_buffer_rad == pytest.approx(math.radians(5))
    thr = p.jump_threshold(np.array([True, False]))
    assert thr[0] == p.jump_threshold_mm and thr[1] == pytest.approx(math.radians(30))
    r = RasterSettings.make(lead_deg=10, tilt_deg=-5, angle_deg=90)
    assert (r.lead_rad, r.tilt_rad, r.angle_rad) == pytest.approx((math.radians(10), math.radians(-5), math.pi / 2))


def test_bad_keys_are_bad_input():
    with pytest.raises(BadInput, match="raster.step_over_mm"):
        RasterSettings.make(step_over_mm=-1)
    with pytest.raises(BadInput, match="unknown key"):
        RasterSettings.make(stepover_mm=5)


def test_home_keeps_the_track_in_mm(tmp_path):
    """The track of seed8 is prismatic: its home value is mm, not degrees (the old cartesian bug)."""
    job_file = tmp_path / "job.toml"
    job_file.write_text(f'[workpiece]\nfile = "{SAMPLES / "sphere_patch.stl"}"\n'
                        '[robot]\nname = "seed8"\nhome_deg = [300.0, 0, 90, 0, 45, 0, 30, 0]\n')
    job = load_job(job_file)
    robot = get_robot("seed8")
    q = home_q(job, robot)
    assert q[0] == 300.0                       # mm, unchanged
    assert q[2] == pytest.approx(math.pi / 2)  # degrees became radians
    settings = JobSettings.from_job(job, robot)
    assert settings.planner.q_home == tuple(q)


def test_home_of_the_wrong_length_is_bad_input(tmp_path):
    job_file = tmp_path / "job.toml"
    job_file.write_text(f'[workpiece]\nfile = "{SAMPLES / "sphere_patch.stl"}"\n[robot]\nhome_deg = [0, 0]\n')
    with pytest.raises(BadInput, match="needs 8 values"):
        home_q(load_job(job_file), get_robot("seed8"))


def test_settings_are_frozen():
    s = RasterSettings.make()
    with pytest.raises(AttributeError):
        s.pitch_mm = 1.0

