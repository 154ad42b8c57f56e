"""camtool.design.objectives on the seed sphere job with a very coarse raster:
objectives, screening, caching (memory and disk), parallel evaluation."""
import json

import numpy as np
import pytest

from camtool.design import DesignProblem, Variable
from camtool.design.objectives import arm_length_mm, check_variables, robot_params, screen_path
from camtool.errors import BadInput
from camtool.job import load_job
from camtool.run.pipeline import robot_for_job

from conftest import SAMPLES

LIGHT = ["workpiece.sample_points=20000", "raster.step_over_mm=20", "raster.pitch_mm=10"]
VARS = [Variable("L1", 300, 600), Variable("L3", 300, 500)]


@pytest.fixture(scope="module")
def job():
    return load_job(SAMPLES / "sphere.toml", LIGHT)


@pytest.fixture(scope="module")
def problem(job):
    p = DesignProblem(job, VARS, coarse=4.0)
    yield p
    p.close()


def test_robot_params_and_arm_length(job):
    assert robot_params(job) == {"L1": 480.0, "L2": 400.0, "L3": 418.0, "L4": 150.0}
    assert arm_length_mm(robot_for_job(job)) == pytest.approx(480 + 400 + 418 + 150)


def test_unknown_variable_is_bad_input(job):
    with pytest.raises(BadInput, match="has no parameter 'X'"):
        check_variables(job, [Variable("X", 1, 2)])
    with pytest.raises(BadInput, match="given twice"):
        check_variables(job, [Variable("L1", 300, 400), Variable("L1", 400, 500)])


def test_coarse_raster_and_screen(problem, job):
    assert problem.path.step_over_mm == pytest.approx(80.0) and problem.path.pitch_mm == pytest.approx(40.0)
    scr = screen_path(problem.path)
    assert 0 < len(scr) < len(problem.path) / 3


def test_objectives_of_a_good_and_a_bad_arm(problem):
    F, v = problem.evaluate([[480, 418], [300, 300]])
    assert F[0, 0] == pytest.approx(1448.0) and F[1, 0] == pytest.approx(300 + 400 + 300 + 150)
    assert v[0] == 0 and v[1] > 0
    good, bad = problem.evaluate_many([[480, 418], [300, 300]])
    assert good.valid and not bad.valid
    assert bad.screened and bad.planner_runs == 1          # the screen alone decided
    assert good.planner_runs == 2                           # screen, then the full coarse plan


def test_cache_rounds_and_counts(problem):
    before_planned, before_runs = problem.planned, problem.planner_runs
    problem.evaluate([[480.2, 417.8], [479.9, 418.4]])      # both round to (480, 418): cached
    assert problem.planned == before_planned and problem.planner_runs == before_runs
    problem.evaluate([[481, 418]])
    assert problem.planned == before_planned + 1


def test_disk_cache_round_trip(job, tmp_path):
    cache = tmp_path / "cache.json"
    with DesignProblem(job, VARS, coarse=4.0, cache_file=cache) as p1:
        F1, v1 = p1.evaluate([[500, 420], [320, 310]])
    data = json.loads(cache.read_text())
    assert len(data["entries"]) == 2
    with DesignProblem(job, VARS, coarse=4.0, cache_file=cache) as p2:
        F2, v2 = p2.evaluate([[500, 420], [320, 310]])
        assert p2.planned == 0 and p2.planner_runs == 0
    assert np.array_equal(F1, F2) and np.array_equal(v1, v2)
    # another raster factor is another problem: the cache is not reused
    with DesignProblem(job, VARS, coarse=6.0, cache_file=cache) as p3:
        p3.evaluate([[500, 420]])
        assert p3.planned == 1


def test_parallel_matches_serial(job, problem):
    X = np.array([[510, 430], [450, 390], [350, 320], [560, 470]], float)
    F1, v1 = problem.evaluate(X)
    with DesignProblem(job, VARS, coarse=4.0, jobs=2) as p2:
        F2, v2 = p2.evaluate(X)
        assert p2.planned == 4
    assert np.array_equal(F1, F2) and np.array_equal(v1, v2)


def test_bad_problem_settings(job):
    with pytest.raises(BadInput, match="--coarse"):
        DesignProblem(job, VARS, coarse=0.5)
    with pytest.raises(BadInput, match="-j"):
        DesignProblem(job, VARS, jobs=0)
