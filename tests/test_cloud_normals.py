"""A cloud's normals in voxel order (camtool.part.cloud_normals): the same normals as open3d's on the file's
order, a dense cloud's surface the same, both against the closed form of the surface the cloud was sampled from."""
import numpy as np
import pytest

from camtool.part import cloud_normals as cn
from camtool.part.cloud_normals import (ORDERED_NORMALS_POINTS, cloud_normals, estimated_normals, spacing_mm,
                                        voxel_order)
from camtool.part.freeform import freeform_surface
from camtool.part.workpiece import load_workpiece
from camtool.settings import FitSettings

R_MM = 400.0          # the cap's sphere
HALF_MM = 150.0       # the cap's half width (x, y)
NOISE_MM = 0.3        # along the true normal


def noisy_cap(n: int, seed: int = 5):
    """(points, true unit normals towards +z, centre) of a sphere cap z = sqrt(R^2 - r^2) - R sampled at random
    with Gaussian noise along its normal; the points in random order, as a scan's."""
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-HALF_MM, HALF_MM, (n, 2))
    c = np.array([0.0, 0.0, -R_MM])
    P = np.column_stack([xy, np.sqrt(R_MM ** 2 - (xy ** 2).sum(1)) - R_MM])
    N = (P - c) / R_MM
    return P + N * rng.normal(0.0, NOISE_MM, n)[:, None], N, c


def angle_deg(a, b):
    """Angle (deg) between unit vectors, sign ignored (a normal's side is the flip's, checked apart)."""
    return np.degrees(np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", a, b)), 0.0, 1.0)))


@pytest.fixture(scope="module")
def dense():
    """A cloud above the threshold: (points, true normals, the sphere's centre, open3d's normals on the points in
    the file's order: the old way)."""
    P, N, c = noisy_cap(ORDERED_NORMALS_POINTS + 50_000)
    return P, N, c, estimated_normals(P, 30)


def test_voxel_order_groups_each_voxel_in_row_major_order():
    rng = np.random.default_rng(0)
    P = rng.uniform(-50, 50, (5000, 3))
    order = voxel_order(P, 7.0)
    assert np.array_equal(np.sort(order), np.arange(len(P)))          # a permutation
    ijk = np.floor((P - P.min(axis=0)) / 7.0).astype(int)[order]
    # independently: lexicographic (i, j, k) never goes back, and within a voxel the file's order stands
    step = np.diff(ijk, axis=0)
    first = np.where(step[:, 0] != 0, step[:, 0], np.where(step[:, 1] != 0, step[:, 1], step[:, 2]))
    assert (first >= 0).all()
    same = (step == 0).all(axis=1)
    assert (np.diff(order)[same] > 0).all()


def test_spacing_of_a_random_cloud_is_its_median_neighbour_distance():
    """From a strided subsample, rescaled by sqrt(share): the closed form of uniform random points in the plane,
    a median nearest-neighbour distance of sqrt(ln 2 / (pi rho))."""
    rng = np.random.default_rng(1)
    P = np.column_stack([rng.uniform(0, 300, (160_000, 2)), np.zeros(160_000)])
    rho = len(P) / 300.0 ** 2
    assert spacing_mm(P) == pytest.approx(np.sqrt(np.log(2) / (np.pi * rho)), rel=0.05)


def test_a_small_cloud_keeps_the_file_order(monkeypatch):
    """Up to the threshold open3d sees the file's order (the shipped scans' normals bit for bit as before)."""
    P, _, _ = noisy_cap(20_000)
    monkeypatch.setattr(cn, "voxel_order", lambda *a: pytest.fail("a small cloud is not reordered"))
    assert np.array_equal(cloud_normals(P, 30), estimated_normals(P, 30))


def test_a_dense_clouds_normals_are_open3ds_on_the_file_order(dense):
    """Above the threshold: the very normals open3d gives the points in the file's order (each point's
    neighbours are the same), towards the origin, and on the cap within the noise's tilt of the closed form."""
    P, N, c, old = dense
    new = cloud_normals(P, 30)
    assert np.array_equal(new, old)
    assert (np.einsum("ij,ij->i", new, -P) >= 0).all()                 # towards the origin, each by its point
    # 30 neighbours of a 0.3 mm-noisy cap 0.6 mm apart tilt by some degrees; the mean is the closed form's
    assert np.median(angle_deg(new, N)) < 10.0


def test_tied_neighbours_of_a_grid_change_no_normal(monkeypatch):
    """An exact grid (distances tie; the search may visit them in another order), reordered (the threshold
    lowered for it): the normals of a tilted plane agree with the file order's to rounding, and with the plane's."""
    monkeypatch.setattr(cn, "ORDERED_NORMALS_POINTS", 10_000)
    X, Y = np.meshgrid(np.arange(160) * 1.0, np.arange(160) * 1.0)
    P = np.column_stack([X.ravel(), Y.ravel(), 0.5 * X.ravel() - 0.25 * Y.ravel() + 7.0])
    P = P[np.random.default_rng(3).permutation(len(P))]
    true = np.tile(np.array([-0.5, 0.25, 1.0]) / np.linalg.norm([-0.5, 0.25, 1.0]), (len(P), 1))
    new, old = cloud_normals(P, 30), estimated_normals(P, 30)
    assert np.abs(new - old).max() < 1e-12
    assert np.abs(np.abs(np.einsum("ij,ij->i", new, true)) - 1.0).max() < 1e-12


def test_a_dense_scans_surface_is_the_old_ones_and_on_the_cap(dense, tmp_path):
    """A dense cloud read from a PLY (the loader's route: normals in voxel order) holds the file order's normals,
    so its free-form surface is the one built the old way; that surface lies on the 0.3 mm-noisy cap at the face's
    nodes: heights within 0.04 mm (p50), 0.1 mm (p99), 0.2 mm at worst (the face's edge, a one-sided window);
    normals within 0.15 deg (p50), 1.5 deg (p99), 2.5 deg at worst of the sphere's."""
    P, _, c, old = dense
    ply = tmp_path / "cap.ply"
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(P)}\n"
            "property double x\nproperty double y\nproperty double z\nend_header\n").encode()
    ply.write_bytes(head + P.astype("<f8").tobytes())
    wp = load_workpiece(ply)
    assert np.array_equal(wp.points_mm, P) and np.array_equal(wp.normals, old)
    s = freeform_surface(wp, FitSettings.make(model="freeform"))
    g = s.grid
    X, Y = np.meshgrid(g.xs, g.ys)
    pts = (s.origin_mm + X[..., None] * s.frame[:, 0] + Y[..., None] * s.frame[:, 1]
           + s.height[..., None] * s.frame[:, 2])
    on = s.material
    radial = np.abs(np.linalg.norm(pts - c, axis=-1)[on] - R_MM)
    true = (pts - c) / np.linalg.norm(pts - c, axis=-1, keepdims=True)
    tilt = angle_deg(s.normals[on], true[on])
    assert np.percentile(radial, 50) < 0.04 and np.percentile(radial, 99) < 0.1 and radial.max() < 0.2
    assert np.percentile(tilt, 50) < 0.15 and np.percentile(tilt, 99) < 1.5 and tilt.max() < 2.5
