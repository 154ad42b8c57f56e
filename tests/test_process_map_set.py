"""camtool.process.map_set: several faces in one program, a free-form face and a plane: a map per face (each as
if alone), the headline figures over all their sites, the files and the 3-D view."""
import numpy as np
import pytest

from camtool.part.surface import Boundary, FaceSet, PlaneSurface
from camtool.process.figures import map_figures, plot_map_png, save_map_npz
from camtool.process.html import process_heat_map_figure
from camtool.process.map_set import FACE_FILE
from camtool.process.maps import track_map
from tests.test_process_mesh_map import POLISH, saddle, saddle_face  # noqa: F401 (a fixture)


def test_several_faces_a_map_each_and_the_figures_of_all(saddle_face, tmp_path):
    """A free-form face and a plane in one program (a FaceSet): a map per face, each as if alone, and the
    headline figures over all their sites, weighted by area."""
    b = Boundary(np.array([[-60, -40], [60, -40], [60, 40], [-60, 40]], float))
    plane = PlaneSurface(np.array([400.0, 0.0, 50.0]), np.array([0, 0, 1.0]), np.array([1, 0, 0.0]),
                         np.array([0, 1, 0.0]), b)
    faces = FaceSet((saddle_face, plane), (3, 7), ({}, {}))
    x = np.arange(-80.0, 80.0, 0.5)
    on_saddle = np.column_stack([x, np.zeros_like(x), saddle(x, 0.0)])
    on_plane = np.column_stack([400 + x[::-1] * 0.5, np.full_like(x, 5.0), np.full_like(x, 50.0)])
    tcp = np.vstack([on_saddle, [[200.0, 0.0, 200.0]], on_plane])
    t = np.arange(len(tcp)) * 0.005
    pm = track_map(POLISH, faces, t, tcp)
    per_face = pm.grid.per_face()
    assert [i for i, _ in per_face] == [3, 7]
    alone = [track_map(POLISH, saddle_face, t, tcp), track_map(POLISH, plane, t, tcp)]
    for (_, m), a in zip(per_face, alone):
        assert m.method == a.method and np.array_equal(m.values, a.values)
    figs = [map_figures(m) for _, m in per_face]
    fig = map_figures(pm)
    areas = [f["worked_area_mm2"] for f in figs]
    assert fig["worked_area_mm2"] == pytest.approx(sum(areas), abs=0.2)
    assert fig["mean"] == pytest.approx(sum(f["mean"] * a for f, a in zip(figs, areas)) / sum(areas), rel=1e-5)
    assert fig["max"] == max(f["max"] for f in figs)
    # the files: each face's own, the set's naming them; the 3-D view draws each face from its file
    for index, m in per_face:
        save_map_npz(m, tmp_path / FACE_FILE.format(index=index))
    npz = save_map_npz(pm, tmp_path / "process_map.npz")
    assert list(np.load(npz)["face_files"]) == [FACE_FILE.format(index=3), FACE_FILE.format(index=7)]
    assert plot_map_png(pm, fig, tmp_path / "plots" / "process_map.png").stat().st_size > 1000
    traces = process_heat_map_figure({**fig, "file": str(npz)}, faces).data
    assert [tr.type for tr in traces] == ["mesh3d", "surface"]
    assert traces[0].cmin == traces[1].cmin and traces[0].cmax == traces[1].cmax
