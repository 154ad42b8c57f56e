"""camtool.process.surface_map: the grid map and a free-form face's mesh map keep the declared interface alike
(the figures, files and report take either without asking which)."""
import numpy as np
import pytest

from camtool.process.grid import MapGrid
from camtool.process.maps import surface_map
from camtool.process.mesh_map import MeshMap
from camtool.process.surface_map import SurfaceMap
from tests.test_process_integrate import plate
from tests.test_process_mesh_map import POLISH, saddle_face  # noqa: F401 (a fixture)


def test_the_interface_cannot_be_half_kept():
    class Half(SurfaceMap):
        def points_mm(self):
            return np.zeros((0, 3))

    with pytest.raises(TypeError):
        Half()


def test_grid_and_mesh_keep_the_interface(saddle_face):
    for sites, kind in ((surface_map(POLISH, plate(200, 100)), MapGrid), (surface_map(POLISH, saddle_face), MeshMap)):
        assert isinstance(sites, SurfaceMap) and isinstance(sites, kind)
        shape = sites.shape
        assert sites.material.shape == shape and sites.area_mm2.shape == shape
        assert sites.points_mm().shape == shape + (3,)
        edge = sites.edge_distance_mm()
        assert edge.shape == shape and (edge[~sites.material] == 0).all() and edge[sites.material].min() > 0
        # the sites on material cover the face's area on the surface
        arrays = sites.npz_arrays()
        assert arrays["layout"] == sites.layout and sites.per_face() == ()
        assert float(sites.area_mm2[sites.material].sum()) > 0
    assert surface_map(POLISH, plate(200, 100)).area_mm2[0, 0] == pytest.approx(POLISH.grid_mm ** 2)
