"""The compiled grid lookups (camtool.motion.grid_bounds) give the numbers of the numpy formula
they replace: nearest node, distance to it, and the ball's lower bound (outside the grid too)."""
import numpy as np
import trimesh

from camtool.motion.geometry import PartGeometry
from camtool.motion.grid_bounds import lower_bounds, nearest_nodes
from camtool.workpiece import Workpiece


def _part():
    box = trimesh.creation.box([300, 200, 100])
    wp = Workpiece(box.vertices, np.zeros_like(box.vertices), np.asarray(box.faces), "box",
                   vertices_mm=np.asarray(box.vertices))
    return PartGeometry.from_workpiece(wp, grid_nodes=5000)


def _numpy_reference(part, p, h):
    idx = np.clip(np.rint((p - part._g_lo) / part._g_cell).astype(np.int64), 0, part._g_shape - 1)
    flat = (idx[:, 0] * part._g_shape[1] + idx[:, 1]) * part._g_shape[2] + idx[:, 2]
    a = np.linalg.norm(p - (part._g_lo + idx * part._g_cell), axis=1)
    t = np.linalg.norm(np.maximum(np.maximum(part._box_lo - p, p - part._box_hi), 0.0), axis=1)
    lb = np.where(part._g_rho[flat] >= a + h, part._g_dist[flat] - a - h - part._slack, -np.inf)
    return flat, a, np.where(t > h, np.maximum(lb, part.horizon_mm + t - h), lb)


def test_compiled_lookups_equal_the_numpy_formula():
    part = _part()
    rng = np.random.default_rng(3)
    p = rng.uniform(-900, 900, (20_000, 3))          # inside the grid and well beyond it
    h = rng.uniform(0, 200, len(p))
    flat, a, lb = _numpy_reference(part, p, h)
    f2, a2 = nearest_nodes(p, part._g_lo, float(part._g_cell), part._g_shape.astype(np.int64))
    assert (f2 == flat).all() and np.allclose(a2, a, rtol=0, atol=1e-9)
    got = lower_bounds(p, h, part._g_lo, float(part._g_cell), part._g_shape.astype(np.int64), part._g_rho,
                       part._g_dist, part._box_lo, part._box_hi, float(part._slack), float(part.horizon_mm))
    assert np.array_equal(np.isinf(got), np.isinf(lb)) and np.allclose(got[np.isfinite(lb)], lb[np.isfinite(lb)],
                                                                        rtol=0, atol=1e-9)
    assert np.isfinite(lb).mean() > 0.3 and (lb > part.horizon_mm).any()   # both branches are exercised
    assert np.allclose(part.lower_bound(p + part.origin_mm, h)[np.isfinite(lb)], lb[np.isfinite(lb)], atol=1e-9)
