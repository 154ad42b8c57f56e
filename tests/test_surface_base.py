"""camtool.part.surface_base: every face the raster works declares the Surface interface, and says what it is
through it (a scan's noise band, a CAD mesh's facets), not through attributes probed for."""
from dataclasses import replace

import numpy as np
import pytest

from camtool.part.freeform import FreeformSurface
from camtool.part.surface import Cylinder, PlaneSurface, SpherePatch
from camtool.part.surface_base import Surface

from test_freeform import FIT, grid_mesh, mesh_workpiece, saddle
from test_surface import rect, sphere_patch, tilted_plane
from camtool.part.fit import fit_surface
from camtool.part.surface import Boundary


def test_the_interface_cannot_be_made_without_its_geometry():
    with pytest.raises(TypeError):
        Surface()


@pytest.mark.parametrize("cls", [PlaneSurface, SpherePatch, Cylinder, FreeformSurface])
def test_every_face_kind_is_a_surface(cls):
    assert issubclass(cls, Surface)


def test_analytic_faces_are_neither_scans_nor_facets_and_lead_on_their_surface():
    for s in (tilted_plane(), sphere_patch()):
        assert not s.scanned and not s.on_mesh_facets and s.lead_band_mm == 0.0


def test_summary_rows_read_the_geometry_back():
    plane = tilted_plane()
    (name, value), = plane.summary_rows()
    assert name == "surface.normal" and np.allclose([float(v) for v in value.split(",")], plane.normal, atol=1e-4)
    bore = Cylinder(np.array([0.0, 0, 0]), 37.5, np.eye(3), Boundary(rect(-1, 1, 0, 100)), concave=True)
    rows = dict(bore.summary_rows())
    assert float(rows["surface.radius_mm"]) == 37.5 and rows["surface.side"] == "inside (concave)"
    assert dict(sphere_patch().summary_rows())["surface.radius_mm"] == "600"


def test_a_free_form_face_says_whether_it_is_a_scan_or_on_a_meshs_facets():
    V, F = grid_mesh(np.linspace(-60, 60, 31), np.linspace(-40, 40, 21), saddle)
    wp, _ = mesh_workpiece(V, F, n=8000)
    mesh = fit_surface(wp, FIT)
    assert mesh.on_mesh_facets and not mesh.scanned
    scan = replace(mesh, source_kind="scan")
    assert scan.scanned and not scan.on_mesh_facets and scan.lead_band_mm >= mesh.lead_band_mm > 0
