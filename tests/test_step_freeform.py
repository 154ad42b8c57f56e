"""A STEP part's free-form B-rep faces (camtool.part.step_freeform): a wavy sheet exported as four B-spline patches
meeting tangentially, with a planar flange at a sharp edge, written by OCP. The patches are one free-form face on
the part's own tessellation, the flange stays its exact plane; the selection works on them."""
from pathlib import Path

import numpy as np
import pytest

from camtool.part.faces import FacesSettings, segment_faces, select_faces
from camtool.part.segment import SegmentSettings
from camtool.part.step import read_step_faces, step_mesh
from camtool.part.step_freeform import BrepMesh, reversed_faces, tangent_groups
from camtool.part.workpiece import load_workpiece

X_MM, Y_MM, FLANGE_Z_MM = 150.0, 100.0, -40.0   # the sheet spans |x| <= X, |y| <= Y; the flange x = X down to Z


def wavy_height_mm(x, y):
    """The sheet: a doubly curved wave with a twist (no plane, sphere or cylinder holds it)."""
    return 15.0 * np.sin(x / 60.0) * np.cos(y / 70.0) + 0.0005 * x * y


def _patch(x0: float, x1: float, y0: float, y1: float, n: int = 12):
    """A B-spline face through an n x n grid of the wave (OCP's least-squares fit, 1e-3 mm)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.collections import Array2_gp_Pnt
    from OCP.GeomAbs import GeomAbs_C2
    from OCP.GeomAPI import GeomAPI_PointsToBSplineSurface
    from OCP.gp import gp_Pnt

    grid = Array2_gp_Pnt(1, n, 1, n)
    for i, x in enumerate(np.linspace(x0, x1, n)):
        for j, y in enumerate(np.linspace(y0, y1, n)):
            grid.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(wavy_height_mm(x, y))))
    surface = GeomAPI_PointsToBSplineSurface(grid, 3, 8, GeomAbs_C2, 1e-3).Surface()
    return BRepBuilderAPI_MakeFace(surface, 1e-6).Face()


def _flange(patches):
    """The plane x = X_MM under the sheet's edge down to FLANGE_Z_MM, bounded by the patches' own edges there."""
    from OCP.BRepAdaptor import BRepAdaptor_Curve
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeEdge, BRepBuilderAPI_MakeFace, BRepBuilderAPI_MakeWire
    from OCP.gp import gp_Pnt
    from OCP.TopAbs import TopAbs_EDGE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    wire = BRepBuilderAPI_MakeWire()
    for face in patches:
        ex = TopExp_Explorer(face, TopAbs_EDGE)
        while ex.More():
            edge = TopoDS.Edge_s(ex.Current()) if hasattr(TopoDS, "Edge_s") else TopoDS.Edge(ex.Current())
            ex.Next()
            c = BRepAdaptor_Curve(edge)
            a, b = c.Value(c.FirstParameter()), c.Value(c.LastParameter())
            if abs(a.X() - X_MM) < 1e-3 and abs(b.X() - X_MM) < 1e-3:
                wire.Add(edge)
    z0, z1 = float(wavy_height_mm(X_MM, -Y_MM)), float(wavy_height_mm(X_MM, Y_MM))
    corners = [(X_MM, Y_MM, z1), (X_MM, Y_MM, FLANGE_Z_MM), (X_MM, -Y_MM, FLANGE_Z_MM), (X_MM, -Y_MM, z0)]
    for p, q in zip(corners[:-1], corners[1:]):
        wire.Add(BRepBuilderAPI_MakeEdge(gp_Pnt(*p), gp_Pnt(*q)).Edge())
    return BRepBuilderAPI_MakeFace(wire.Wire(), True).Face()


def wavy_panel_step(path: Path, flange: bool = True) -> Path:
    """Write the wavy sheet as four B-spline patches (split at x = 0 and y = 0) sewn together, with the flange."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_Sewing
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    from camtool.part.step import _ocp_output_to_log

    patches = [_patch(x0, x1, y0, y1) for x0, x1 in ((-X_MM, 0.0), (0.0, X_MM)) for y0, y1 in ((-Y_MM, 0.0), (0.0, Y_MM))]
    sew = BRepBuilderAPI_Sewing(0.01)
    for face in patches + ([_flange(patches)] if flange else []):
        sew.Add(face)
    sew.Perform()
    with _ocp_output_to_log():
        writer = STEPControl_Writer()
        writer.Transfer(sew.SewedShape(), STEPControl_AsIs)
        writer.Write(str(path))
    return Path(path)


@pytest.fixture(scope="module")
def panel(tmp_path_factory):
    """The part's file, its workpiece (placed as given) and its faces."""
    path = wavy_panel_step(tmp_path_factory.mktemp("step") / "wavy_panel.step")
    wp = load_workpiece(path, "mm")
    settings = FacesSettings("all", SegmentSettings(), path, np.eye(4))
    return path, wp, segment_faces(settings, wp)


def test_the_file_holds_four_bspline_patches_and_a_plane(panel):
    path, _, _ = panel
    assert [f.model for f in read_step_faces(path)] == ["other"] * 4 + ["plane"]


def test_tangent_patches_are_one_group_and_the_flange_apart(panel):
    path = panel[0]
    V, F, owner = step_mesh(path)
    mesh = BrepMesh(V, F, owner)
    assert [g.tolist() for g in tangent_groups(mesh, np.arange(4), 30.0)] == [[0, 1, 2, 3]]
    # with the flange among them (a 90-odd degree edge) it stays apart; a key below the patches' seams splits
    # them (their tessellations' normals across a seam differ by a few degrees, not zero)
    assert [g.tolist() for g in tangent_groups(mesh, np.arange(5), 30.0)] == [[0, 1, 2, 3], [4]]
    assert len(tangent_groups(mesh, np.arange(4), 1e-6)) == 4


def test_the_patches_are_one_freeform_face_on_the_parts_own_triangles(panel):
    path, wp, seg = panel
    assert [f.model for f in seg.faces] == ["freeform", "plane"]
    sheet, flange = seg.faces
    P = wp.points_mm
    on_sheet = P[:, 0] < X_MM - 1.0
    assert np.isin(np.flatnonzero(on_sheet), sheet.inliers).mean() > 0.99
    assert (P[flange.inliers, 0] > X_MM - 1e-6).all()
    assert seg.unassigned < 0.005 * seg.n_points
    # area against the wave's own surface integral (independent: a dense grid of sqrt(1 + hx^2 + hy^2))
    x, y = np.meshgrid(np.linspace(-X_MM, X_MM, 1201), np.linspace(-Y_MM, Y_MM, 801), indexing="ij")
    hx, hy = np.gradient(wavy_height_mm(x, y), x[:, 0], y[0], edge_order=2)
    true_area = np.trapezoid(np.trapezoid(np.sqrt(1 + hx ** 2 + hy ** 2), y[0], axis=1), x[:, 0])
    assert abs(sheet.area_mm2 - true_area) < 0.01 * true_area
    # the surface's points lie on the wave (the tessellation is within DEFLECTION_MM, the fit 1e-3 mm)
    s = sheet.surface
    u, v = np.meshgrid(np.linspace(-100, 100, 21), np.linspace(-60, 60, 13))
    Q = s.point_mm(u, v)
    assert np.abs(Q[..., 2] - wavy_height_mm(Q[..., 0], Q[..., 1])).max() < 0.06
    # the normals point away from the material side the B-rep gives (the sheet's normals: up)
    assert (s.normal_at(u, v)[..., 2] > 0.8).all()


def test_select_works_on_the_freeform_face(panel):
    _, wp, seg = panel
    assert [f.index for f in select_faces(seg, "freeform", wp)] == [0]
    assert [f.index for f in select_faces(seg, {"nearest_mm": [0.0, 0.0, 0.0]}, wp)] == [0]
    assert [f.index for f in select_faces(seg, {"nearest_mm": [X_MM, 0.0, -30.0]}, wp)] == [1]
    assert [f.index for f in select_faces(seg, [1], wp)] == [1]


def test_a_patch_wound_the_other_way_is_turned_to_agree(panel):
    """An open shell's patches need not agree on a side: one wound the other way is found across the tangent
    seams (and the flange, across a sharp edge, tells nothing)."""
    V, F, owner = step_mesh(panel[0])
    assert reversed_faces(BrepMesh(V, F, owner), np.arange(4)).tolist() == []
    for k in (1, 3):
        G = np.where((owner == k)[:, None], F[:, ::-1], F)
        assert reversed_faces(BrepMesh(V, G, owner), np.arange(4)).tolist() == [k]
        others = [i for i in range(4) if i != k]
        assert reversed_faces(BrepMesh(V, G, owner), np.array([k, *others])).tolist() == others   # from face k


def test_the_flange_keeps_its_brep_area(panel):
    """The analytic flange's boundary stays on its B-rep edges: its area is its own triangles' (the sheet's points
    beside it are the free-form face's, never the plane's extent)."""
    path, _, seg = panel
    V, F, owner = step_mesh(path)
    T = V[F[owner == 4]]
    brep_area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1).sum()
    assert abs(seg.faces[1].area_mm2 - brep_area) < 0.01 * brep_area
