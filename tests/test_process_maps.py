"""camtool.process.maps: which map a surface gets (a grid; a free-form face or a cylinder its own mesh); a map too
fine refused before planning, a free-form face's too."""
import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.part.surface import Boundary, Cylinder, FaceSet
from camtool.process.maps import check_map_size, on_mesh, surface_map
from camtool.settings import ProcessSettings
from tests.test_process_integrate import plate
from tests.test_process_mesh_map import POLISH, saddle_face  # noqa: F401 (a fixture)


def test_free_form_faces_get_their_mesh_and_the_others_a_grid(saddle_face):
    assert on_mesh(saddle_face) and not on_mesh(plate())
    assert surface_map(POLISH, saddle_face).layout == "mesh"
    assert surface_map(POLISH, plate()).layout == "grid"
    cylinder = Cylinder(np.zeros(3), 80.0, np.eye(3), Boundary(np.array([[-1, -50], [1, -50], [1, 50], [-1, 50.0]])))
    assert on_mesh(cylinder) and surface_map(POLISH, cylinder).layout == "mesh"


def test_too_fine_is_one_line_for_each_face_of_several(saddle_face):
    fine = ProcessSettings.make(kind="polish", diameter_mm=30, grid_mm=0.06)
    check_map_size(POLISH, FaceSet((saddle_face, plate()), (0, 1), ({}, {})))
    with pytest.raises(BadInput, match="vertices"):
        check_map_size(fine, saddle_face)
    with pytest.raises(BadInput, match="process.grid_mm"):
        check_map_size(fine, FaceSet((plate(20, 20), saddle_face), (0, 1), ({}, {})))
