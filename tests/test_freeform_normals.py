"""freeform_normals: a scan's normals averaged along its surface, against closed forms and direct sums."""
import math

import numpy as np

from camtool.part.freeform import freeform_surface
from camtool.part.freeform_grid import Grid, normals_of
from camtool.part.freeform_normals import (POINTS_FROM_DEG, POINTS_FULL_DEG, STEEP_FROM_DEG, point_normals,
                                          surface_normals)
from camtool.part.workpiece import Workpiece
from camtool.settings import FitSettings

FIT = FitSettings(model="freeform", threshold_mm=1.0, iterations=100, min_inlier_ratio=0.5, seed=0,
                  boundary_cell_mm=5.0, close_gaps_mm=5.0, simplify_mm=0.5)


def _cylinder_scan(radius_mm=300.0, half_angle_deg=70.0, length_mm=200.0, n=60_000, noise_mm=1.0, seed=46):
    """A cylinder's skin (axis along y, through the origin, bulging to +z) over +-half_angle_deg, uniform on its
    area, each point moved along its radial normal by Gaussian noise: (points, normals)."""
    rng = np.random.default_rng(seed)
    a = np.radians(rng.uniform(-half_angle_deg, half_angle_deg, n))
    y = rng.uniform(-0.5 * length_mm, 0.5 * length_mm, n)
    radial = np.stack([np.sin(a), np.zeros(n), np.cos(a)], axis=1)
    P = (radius_mm + rng.normal(0.0, noise_mm, n))[:, None] * radial + np.stack([0 * y, y, 0 * y], axis=1)
    return P, radial


def test_a_noisy_cylinder_scans_normals_follow_its_radial_normal_on_its_steep_flanks():
    """A 1 mm-noise scan of a cylinder of R 300 mm over +-70 deg (its flanks 70 deg from the chart plane): the
    surface's normals at its material nodes against the closed form, the radial direction through the node's
    surface point: 0.70 deg p95 (1.6 over 60 deg of tilt); on the chart's window 1.11 (4.6 over 60 deg)."""
    P, N = _cylinder_scan()
    s = freeform_surface(Workpiece(P, N, source="cylinder.xyz"), FIT)
    xy = s.grid.node_xy()[s.material]
    jj, ii = np.nonzero(s.material)
    h = s.grid.interp(s.height, xy[:, 0], xy[:, 1])
    pts = s.origin_mm + xy[:, :1] * s.frame[:, 0] + xy[:, 1:] * s.frame[:, 1] + h[:, None] * s.frame[:, 2]
    radial = pts * np.array([1.0, 0.0, 1.0])
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    err = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", s.normals[jj, ii], radial), -1, 1)))
    tilt = np.degrees(np.arccos(np.abs(radial @ s.frame[:, 2])))
    assert tilt.max() > 60.0                                  # the face reaches its steep flanks
    assert np.percentile(err, 95) < 0.9, np.percentile(err, [50, 95, 100])
    # the last 10 deg to the edge: a window there is one-sided (its mean leans inwards)
    assert np.percentile(err[tilt > 60], 95) < 2.5, np.percentile(err[tilt > 60], [50, 95, 100])


def _direct(h, g, frame, sigma_mm, j, i):
    """The area-weighted mean of the height field's normals with the Gaussian of the 3-D distance from node (j, i),
    summed over every node (no lattice, no window cut)."""
    ny, nx = h.shape
    J, I = np.indices(h.shape)
    raw = normals_of(h, g, frame, 0.0)
    d2 = ((J - j) ** 2 + (I - i) ** 2) * g * g + (h - h[j, i]) ** 2
    w = np.exp(-0.5 * d2 / sigma_mm ** 2) / (raw @ frame[:, 2])
    m = (w[..., None] * raw).sum(axis=(0, 1))
    return m / np.linalg.norm(m)


def test_surface_window_is_the_direct_sum_over_the_nodes_and_the_chart_window_where_level():
    """On a steep analytic height field (a cylinder of R 80 mm, to 75 deg) the lattice-summed window agrees with the
    direct sum over all nodes within 0.25 deg up to ``POINTS_FULL_DEG`` of tilt (steeper, a scan's normals are its
    points'); where the field is level it is ``normals_of``'s chart average."""
    g, R, sigma = 1.0, 80.0, 6.0
    grid = Grid(-78.0, -40.0, g, 157, 81)
    X = grid.node_xy()[..., 0]
    h = np.sqrt(R * R - X ** 2)
    frame = np.eye(3)
    out = surface_normals(h, g, frame, sigma)
    chart = normals_of(h, g, frame, sigma)
    for x in (-60.0, -50.0, -45.0, 40.0, 55.0):            # 49, 39, 34, 30 and 43 deg of tilt
        i = int(round((x - grid.x0) / g))
        ref = _direct(h, g, frame, sigma, 40, i)
        assert math.degrees(math.acos(min(1.0, float(out[40, i] @ ref)))) < 0.25, x
    level = np.degrees(np.arccos(np.clip(chart @ frame[:, 2], -1, 1))) < STEEP_FROM_DEG
    assert level.any() and np.array_equal(out[level], chart[level])
    steep = np.abs(X) > 70.0                                  # there the chart's window is far off the surface's
    i = int(round((75.0 - grid.x0) / g))
    assert math.degrees(math.acos(float(chart[40, i] @ _direct(h, g, frame, sigma, 40, i)))) > 1.0
    assert steep.any()


def test_steep_nodes_take_the_normal_of_their_points():
    """Points on a cylinder of R 80 mm (axis along y) to 80 deg of tilt, its height field exact but its normals
    the chart's (far off where steep): ``point_normals`` gives its nodes over ``POINTS_FULL_DEG`` the radial normal
    through their surface point within 0.5 deg (its lattice interpolated), and leaves the nodes under
    ``POINTS_FROM_DEG`` as they were."""
    g, R, foot = 1.0, 80.0, 6.0
    grid = Grid(-78.0, -40.0, g, 157, 81)
    X = grid.node_xy()[..., 0]
    h = np.sqrt(R * R - X ** 2)
    frame = np.eye(3)
    chart = normals_of(h, g, frame, 10.0)
    a = np.radians(np.linspace(-80.0, 80.0, 1600))
    y = np.linspace(-40.0, 40.0, 161)
    A, Y = np.meshgrid(a, y)
    xyh = np.stack([R * np.sin(A).ravel(), Y.ravel(), R * np.cos(A).ravel()], axis=1)
    out = point_normals(chart, h, grid, frame, xyh, foot, np.ones(h.shape, bool))
    tilt = np.degrees(np.arccos(np.clip(chart @ frame[:, 2], -1, 1)))
    radial = np.stack([X / R, 0 * X, h / R], axis=-1)
    rows = slice(20, 61)                                  # away from the cloud's ends along the axis
    steep = (tilt >= POINTS_FULL_DEG) & (np.abs(X) < 76.0)  # ... and 2 footprints inside its rims (80 deg)
    err = np.degrees(np.arccos(np.clip((out * radial).sum(-1), -1, 1)))
    assert steep[rows].sum() > 100
    assert err[rows][steep[rows]].max() < 0.5, err[rows][steep[rows]].max()
    assert np.degrees(np.arccos(np.clip((chart * radial).sum(-1), -1, 1)))[rows][steep[rows]].max() > 2.0
    level = tilt < POINTS_FROM_DEG
    assert np.array_equal(out[level], chart[level])
