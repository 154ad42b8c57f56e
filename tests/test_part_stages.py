"""The workpiece and fit stages (camtool.run.part_stages), and the same made ahead in a forked process."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.job import load_job
from camtool.run.part_stages import PartAhead, surface_for_job, workpiece_for_job

from conftest import ROOT


def _job(*overrides):
    return load_job(ROOT / "samples" / "sphere.toml", list(overrides))


def test_the_part_made_ahead_is_the_part_made_here():
    """``camtool run`` reads and fits the workpiece in a child while it imports the pipeline: the same
    workpiece and surface as the stages make in the run's own process."""
    job = _job()
    wp = workpiece_for_job(job)
    surface = surface_for_job(job, wp)
    with PartAhead(job) as ahead:
        wp2, surface2 = ahead.workpiece(), ahead.surface()
    assert np.array_equal(wp.points_mm, wp2.points_mm) and np.array_equal(wp.normals, wp2.normals)
    assert type(surface) is type(surface2) and np.array_equal(surface.center_mm, surface2.center_mm)
    assert surface.radius_mm == surface2.radius_mm and surface.stats == surface2.stats


def test_a_fit_that_fails_fails_at_the_fit_stage():
    """The workpiece stage succeeds (its warnings are shown), then the fit's own error is raised."""
    with PartAhead(_job("fit.model=\"plane\"", "fit.min_inlier_ratio=0.9")) as ahead:   # a plane on a sphere patch
        assert len(ahead.workpiece().points_mm) > 1000
        with pytest.raises(BadInput, match="min_inlier_ratio"):
            ahead.surface()


def test_a_file_that_cannot_be_read_fails_at_the_workpiece_stage(tmp_path):
    job_file = tmp_path / "job.toml"
    job_file.write_text((ROOT / "samples" / "sphere.toml").read_text().replace("sphere_patch.stl", "missing.stl"))
    with PartAhead(load_job(job_file)) as ahead:
        with pytest.raises(BadInput, match="not found"):
            ahead.workpiece()
