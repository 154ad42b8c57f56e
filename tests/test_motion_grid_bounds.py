"""The compiled grid lookups (camtool.motion.grid_bounds) give the numbers of the numpy formula
they replace: nearest node, distance to it, and the ball's lower bound (outside the grid too)."""
import subprocess
import sys

import numpy as np
import trimesh

from camtool.motion.geometry import PartGeometry
from camtool.motion.grid_bounds import load_compiled, lower_bounds, nearest_nodes
from camtool.part.workpiece import Workpiece


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


def test_loading_ahead_covers_the_argument_types_the_check_passes():
    """``load_compiled`` (run while the check's process waits) loads every signature the part's bounds call:
    a call with another type would compile in the check itself (0.6 s and more). In a fresh process, as the
    check's, so that no other test's calls count."""
    code = """
import numpy as np, trimesh
from camtool.motion.geometry import PartGeometry
from camtool.motion.grid_bounds import load_compiled, lower_bounds, nearest_nodes
from camtool.part.workpiece import Workpiece
load_compiled()
known = (len(lower_bounds.signatures), len(nearest_nodes.signatures))
box = trimesh.creation.box([300, 200, 100])
part = PartGeometry.from_workpiece(Workpiece(box.vertices, np.zeros_like(box.vertices), np.asarray(box.faces),
                                             "box", vertices_mm=np.asarray(box.vertices)), grid_nodes=5000)
p = np.random.default_rng(4).uniform(-400, 400, (50, 3)) + part.origin_mm
part.lower_bound(p, 10.0)
part.lower_bound(p, np.full(len(p), 10.0))
part.upper_bound_distance(p)
part.above(p, np.full(len(p), 10.0), 5.0)
print(*known, len(lower_bounds.signatures), len(nearest_nodes.signatures))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    known, after = [int(x) for x in out[:2]], [int(x) for x in out[2:]]
    assert after == known and min(known) > 0
