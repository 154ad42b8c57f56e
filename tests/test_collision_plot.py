"""Obstacles drawn in report.html (camtool.collision.plot) from report.json's collision world."""
import numpy as np
import plotly.graph_objects as go

from camtool.collision import CellSettings, CollisionWorld
from camtool.collision.plot import obstacle_traces
from camtool.collision.shapes import WORLD, Body
from camtool.robots import get_robot
from camtool.transforms import matrix_from_xyz_rpy


def test_every_obstacle_is_drawn_where_it_is():
    T = matrix_from_xyz_rpy([1000.0, 0.0, -50.0], [0.0, 0.0, 30.0])
    box = Body("table", "obstacle", WORLD, "box", (600.0, 1200.0, 40.0), T)
    post = Body("post", "obstacle", WORLD, "cylinder", (30.0, 700.0), matrix_from_xyz_rpy([600, 560, 300], [0, 0, 0]))
    floor = Body("floor", "obstacle", WORLD, "halfspace", (-400.0,), np.eye(4))
    world = CollisionWorld(get_robot("seed8"), CellSettings(obstacles=(box, post, floor)))
    traces = obstacle_traces(go, {"motion_check": {"cell": world.describe()}})
    assert [t.name for t in traces] == ["obstacle table", "obstacle post", "obstacle floor"]
    V = np.c_[traces[0].x, traces[0].y, traces[0].z]
    assert np.allclose(V.mean(axis=0), [1000.0, 0.0, -50.0], atol=0.1)
    assert np.allclose(sorted({round(z, 1) for z in traces[0].z}), [-70.0, -30.0])
    assert set(traces[2].z) == {-400.0}
    assert obstacle_traces(go, {"motion_check": {}}) == [] and obstacle_traces(go, {}) == []
