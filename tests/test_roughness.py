"""part/roughness.py: a CAD mesh's vertices lie on its smooth surface, a scan's carry noise (independent
reference: the noise drawn, and the closed-form surface the vertices were put on)."""
import numpy as np
import pytest

from camtool.part.roughness import (BAND_MAX_MM, BAND_QUANTILE, CAD_COPLANAR_SHARE, SCAN_ROUGHNESS_MM, mesh_roughness,
                                   vertex_residuals)


def sheet(noise_mm=0.0, n=60, spacing_mm=2.0, seed=0):
    """Vertices of a curved sheet z = x^2 / 400 - y^2 / 600 (a saddle, R 200-300 mm) on a 2 mm grid."""
    x, y = np.meshgrid(np.arange(n) * spacing_mm, np.arange(n) * spacing_mm)
    x, y = x.ravel() - x.mean(), y.ravel() - y.mean()
    z = x**2 / 400.0 - y**2 / 600.0 + np.random.default_rng(seed).normal(0.0, noise_mm, x.size)
    return np.c_[x, y, z]


def test_cad_vertices_on_a_curved_surface_are_smooth():
    r = mesh_roughness(sheet())
    assert not r.is_scan
    assert r.median_mm < 1e-5      # a quadric in the neighbours' frame holds the saddle to third order
    assert np.abs(vertex_residuals(sheet())).max() < 1e-3


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_vertices_are_a_scan_with_the_noise_band(seed):
    sigma = 0.05
    r = mesh_roughness(sheet(sigma, seed=seed))
    assert r.is_scan and r.median_mm > SCAN_ROUGHNESS_MM
    # the residual is the vertex's noise less its neighbours' fit (79 of them, two 5 mm sigmas on the 2 mm grid:
    # about 1 % in quadrature): the band is the drawn noise's own quantile
    noise = np.random.default_rng(seed).normal(0.0, sigma, 3600)
    assert r.band_mm == pytest.approx(np.percentile(np.abs(noise), BAND_QUANTILE), rel=0.1)


def test_the_band_is_capped():
    r = mesh_roughness(sheet(1.0))
    assert r.is_scan and r.band_mm == BAND_MAX_MM


def test_coincident_corners_count_once():
    """An STL or a triangle soup stores each corner once per triangle; a copy must not pin the quadric."""
    V = sheet(0.05)
    soup = np.repeat(V, 6, axis=0)
    assert mesh_roughness(soup) == mesh_roughness(V)


@pytest.mark.parametrize("n", [0, 3, 6])
def test_too_few_vertices_are_not_judged(n):
    assert not mesh_roughness(sheet(0.1)[:n]).is_scan


def test_the_workpiece_says_whether_a_mesh_is_a_scan():
    noisy, smooth = sheet(0.05), sheet()
    assert mesh_roughness(noisy, scan="no") == mesh_roughness(noisy, scan="no")
    assert not mesh_roughness(noisy, scan="no").is_scan and mesh_roughness(noisy, scan="no").band_mm == 0.0
    forced = mesh_roughness(smooth, scan="yes")
    assert forced.is_scan and forced.band_mm < 0.01      # a scan as smooth as CAD: its band a tenth of the CAD tolerance


def test_the_band_is_measured_over_two_smoothing_sigmas():
    """Roughness correlated over a few mm (a laser scan's waviness) is in the band only when the neighbourhood
    spans it: a 12 mm ripple of 0.1 mm over white noise of 0.01 mm (p99.99 of |noise| 0.039 mm)."""
    V = sheet(0.01)
    V[:, 2] += 0.1 * np.sin(2 * np.pi * V[:, 0] / 12.0)
    narrow = mesh_roughness(V, smoothing_mm=1.0).band_mm     # 12 neighbours (+-4 mm): the quadric follows the ripple
    wide = mesh_roughness(V, smoothing_mm=5.0).band_mm       # 79 neighbours (+-10 mm): the ripple is roughness
    assert narrow < 0.06 and wide > 0.1


def _triangulated(V, n=60):
    """The grid sheet's vertices (n x n, row-major) as a mesh: two triangles per cell."""
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    a = (j * n + i).ravel()
    return np.r_[np.c_[a, a + 1, a + n + 1], np.c_[a, a + n + 1, a + n]]


def test_a_rough_mesh_with_noise_is_a_scan_even_with_its_triangles():
    V = sheet(0.05)
    r = mesh_roughness(V, faces=_triangulated(V))
    assert r.is_scan and r.coplanar_share < CAD_COPLANAR_SHARE / 3    # noise leaves no two triangles coplanar


def test_a_coarse_tessellation_cut_along_its_cells_is_cad():
    """A 25 mm height-field grid of a wave (rough to the quadric: facets far coarser than its curvature), each cell
    cut into four triangles at its centre put on the cell's own facet plane (as a mesher splits facets): CAD."""
    n, g = 21, 25.0
    x, y = np.meshgrid(np.arange(n) * g, np.arange(n) * g)
    z = 40.0 * np.sin(x / 60.0) * np.cos(y / 70.0)
    V = np.c_[x.ravel(), y.ravel(), z.ravel()]
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    a = (j * n + i).ravel()
    c0, c1, c2, c3 = a, a + 1, a + n + 1, a + n
    centre = 0.5 * (V[c0] + V[c2])                  # on the diagonal c0-c2: in the plane of both its triangles
    k = len(V) + np.arange(len(a))
    V = np.r_[V, centre]
    F = np.r_[np.c_[c0, c1, k], np.c_[c1, c2, k], np.c_[c2, c3, k], np.c_[c3, c0, k]]
    assert mesh_roughness(V).is_scan                               # by its vertices alone it looks rough
    r = mesh_roughness(V, faces=F)
    assert not r.is_scan and r.band_mm == 0.0 and r.coplanar_share >= CAD_COPLANAR_SHARE
    assert mesh_roughness(V, faces=F, scan="yes").is_scan           # the workpiece still has the last word


@pytest.mark.parametrize("name,scale,is_scan", [("noether_wavy_hole.ply", 50.0, False),
                                                 ("snp_dome_scan.ply", 1000.0, True)])
def test_the_vendored_wavy_sheet_is_cad_and_the_dome_scan_a_scan(name, scale, is_scan):
    import trimesh
    from pathlib import Path
    m = trimesh.load(Path(__file__).parents[1] / "benchmarks" / "parts" / "freeform" / name, process=False)
    assert mesh_roughness(np.asarray(m.vertices) * scale, faces=m.faces).is_scan == is_scan


def test_the_verdict_is_remembered_for_the_same_mesh_and_only_for_it(monkeypatch):
    """A run asks whether its mesh is a scan once per plan: the second ask of the same mesh and rule does not judge
    again; another mesh, or another rule, is judged afresh."""
    import camtool.part.roughness as rough

    calls = []
    real = rough._judged
    monkeypatch.setattr(rough, "_judged", lambda *a: calls.append(1) or real(*a))
    monkeypatch.setattr(rough, "_VERDICTS", {})
    rng = np.random.default_rng(0)
    V = rng.uniform(0, 100, (300, 3))
    F = np.array([[0, 1, 2], [2, 3, 4]])
    first = rough.mesh_is_scan(V, "auto", F)
    assert rough.mesh_is_scan(V, "auto", F) == first and len(calls) == 1
    rough.mesh_is_scan(V, "no", F)
    W = V.copy()
    W[0, 0] += 1e-3
    rough.mesh_is_scan(W, "auto", F)
    assert len(calls) == 3


@pytest.mark.parametrize("noise_mm", [0.0, 0.05])
def test_the_verdict_handed_to_the_motion_check_gives_its_band(monkeypatch, noise_mm):
    """The run hands the motion check the verdict its plan made (``stages.with_scan_verdict``: workpiece.scan "yes"
    or "no"); the check's noise band from it is the band judged from nothing ("auto"), a CAD mesh's without judging
    it again; a mesh this process never judged keeps "auto" (the check judges it)."""
    from dataclasses import dataclass
    from types import SimpleNamespace

    import camtool.part.roughness as rough
    from camtool.run.stages import scanned_mesh_band_mm, with_scan_verdict
    from camtool.settings import WorkpieceSettings

    @dataclass(frozen=True)
    class Settings:
        workpiece: WorkpieceSettings

    monkeypatch.setattr(rough, "_VERDICTS", {})
    V = sheet(noise_mm)
    F = np.array([[0, 1, 60], [1, 61, 60]])
    wp = SimpleNamespace(vertices_mm=V, faces=F)
    settings = Settings(WorkpieceSettings(file="sheet.stl", units="mm", sample_points=0, normal_neighbours=30,
                                          drop_nonfinite=True))
    assert with_scan_verdict(settings, wp) is settings
    fresh = scanned_mesh_band_mm(wp, 0.0, "auto")
    assert rough.mesh_is_scan(V, "auto", F) == (noise_mm > 0)
    handed = with_scan_verdict(settings, wp).workpiece.scan
    assert handed == ("yes" if noise_mm > 0 else "no")
    calls = []
    real = rough._judged
    monkeypatch.setattr(rough, "_judged", lambda *a: calls.append(a[1]) or real(*a))
    assert scanned_mesh_band_mm(wp, 0.0, handed) == fresh and (fresh > 0) == (noise_mm > 0)
    assert calls == (["yes"] if noise_mm > 0 else [])   # a scan's band needs its residuals; CAD: nothing
