"""NSGA-II (pymoo, optional extra) on the design problem and the hypervolume indicator."""
import json

import numpy as np
import pytest

pytest.importorskip("pymoo")

from click.testing import CliRunner  # noqa: E402

from camtool.cli import cli as group  # noqa: E402
from camtool.design import nondominated_mask  # noqa: E402
from camtool.design.nsga2 import hypervolume, run_nsga2  # noqa: E402

from conftest import SAMPLES  # noqa: E402


def test_hypervolume_of_known_fronts():
    # two points (1,3) and (2,1) against (4,4): union of [1,4]x[3,4] and [2,4]x[1,4] = 3 + 6 = 9 - overlap 2 = 7
    assert hypervolume([[1, 3], [2, 1]], [4, 4]) == pytest.approx(7.0)
    assert hypervolume([[1, 1]], [4, 4]) == pytest.approx(9.0)
    assert hypervolume(np.zeros((0, 2)), [4, 4]) == 0.0
    # a dominated point adds nothing
    assert hypervolume([[1, 3], [2, 1], [3, 3]], [4, 4]) == pytest.approx(7.0)


def schaffer_with_hole(X):
    X = np.atleast_2d(X)
    F = np.column_stack([X[:, 0] + X[:, 1], (X[:, 0] - 1) ** 2 + (X[:, 1] - 1) ** 2])
    return F, np.where(X.sum(axis=1) < 0.6, 1.0, 0.0)


def test_nsga2_budget_front_and_seed():
    a = run_nsga2(schaffer_with_hole, [0, 0], [1, 1], budget=48, pop_size=8, seed=2, resolution=0.01)
    b = run_nsga2(schaffer_with_hole, [0, 0], [1, 1], budget=48, pop_size=8, seed=2, resolution=0.01)
    assert 48 <= a.evaluations <= 48 + 8
    assert np.array_equal(a.front_F, b.front_F)
    assert len(a.front_F) >= 2 and nondominated_mask(a.front_F).all()
    F, v = schaffer_with_hole(a.front_X)
    assert np.all(v == 0) and np.allclose(F, a.front_F)
    assert np.allclose(a.front_X, np.round(a.front_X / 0.01) * 0.01)


def test_cli_nsga2_tiny(tmp_path):
    args = ["design", str(SAMPLES / "sphere.toml"), "--method", "nsga2", "--vary", "L1=400:600",
            "--vary", "L3=350:500", "--particles", "4", "--explore-iters", "1", "--iters", "1",
            "--max-checks", "3", "--set", "workpiece.sample_points=20000", "--set", "raster.step_over_mm=20",
            "--set", "raster.pitch_mm=10", "--json", "-o", str(tmp_path)]
    r = CliRunner().invoke(group, args, catch_exceptions=False)
    assert r.exit_code == 0, r.output
    d = json.loads(r.output)
    assert d["method"] == "nsga2" and d["narrowed"] is None
    assert 12 <= d["evaluations"] <= 16
    assert d["chosen"]["full"]["unreachable"] == 0
