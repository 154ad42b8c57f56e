"""Write the sample workpieces into samples/ (deterministic; run from anywhere).

- sphere_patch.stl: the seed patch (R 600 mm, elevation -10..60 deg, azimuth
  -40..40 deg) in its own frame: centre at the origin, outward normals towards -x;
  0.5 deg grid, chordal error below 0.02 mm.
- sphere_scan.ply: a scan of that patch, 50k points, sigma 0.1 mm, no normals.
- wall.ply: seed 002's target plane y = 600 mm, x -450..450, z 150..1050 mm,
  sigma 0.1 mm plus 20 % outliers (50k points).
- plate_hole.stl: the top face (z = 0) of a 400 x 300 mm plate with an 80 x 80 mm
  square hole centred at (60, 30) mm; one-sided, normals +z.

Multi-face parts (issue 26), each as a mesh (``<part>.stl``) and as a noisy
scan (``<part>_scan.ply``: 60k points, sigma 0.1 mm, normals estimated by
open3d from 30 neighbours and oriented out of the material, as a scanner's
software does), with the truth of every face in ``faces_truth.json`` (model,
parameters, and the face's outline sampled every 2 mm):

- box_open: a 300 x 200 x 150 mm box without its bottom (five planes);
- pipe_half: half a pipe section, R 120 mm outside and 100 mm inside, 300 mm
  long along x (two cylinders, one concave; two half-ring ends; two coplanar
  cut strips);
- dome_cylinder: a hemisphere R 100 mm on a cylinder R 100 mm, 150 mm tall,
  open at the bottom (a cylinder and a sphere, tangent);
- plate_chamfer: a 300 x 200 x 20 mm plate whose top edges carry a 10 mm
  45 deg chamfer (top, four chamfers, four sides; no bottom).

pipe_half is also written as STEP (``pipe_half.step``, OCP), its faces exact.

Free-form parts (issue 46), no plane, sphere or cylinder among them (``make_freeform``):

- freeform_hood.stl: the top skin of a car-hood-like panel, 700 mm long (x) and
  470 mm wide at the front narrowing to 440 mm at the back, a crown of 40 mm with
  a cubic twist across it (no quadric fits it); 5 mm grid, normals +z;
- freeform_shell_scan.ply: a raw scan of a shell: an elliptic dome (semi-axes
  250 x 180 x 90 mm, cut at z = 55 mm: 400 x 285 mm) with a bump (12 mm, sigma 50 mm) and two
  round holes (R 25 mm), 60k points with 1.0 mm of noise along the normal and
  0.5 % outliers, normals estimated by open3d from 30 neighbours and oriented
  out of the material (as the other scans: a scanner's software does).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

OUT = Path(__file__).resolve().parent.parent / "samples"
R_MM = 600.0
AZ_DEG = (-40.0, 40.0)
EL_DEG = (-10.0, 60.0)


def patch_point(az, el, r=R_MM):
    """Point on the seed patch (own frame), facing -x."""
    return np.asarray(r)[..., None] * np.stack([-np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=-1)


def sphere_patch_mesh(step_deg: float = 0.5) -> trimesh.Trimesh:
    az = np.radians(np.linspace(*AZ_DEG, int(round((AZ_DEG[1] - AZ_DEG[0]) / step_deg)) + 1))
    el = np.radians(np.linspace(*EL_DEG, int(round((EL_DEG[1] - EL_DEG[0]) / step_deg)) + 1))
    A, E = np.meshgrid(az, el, indexing="ij")
    verts = patch_point(A, E).reshape(-1, 3)
    ne = len(el)
    i, j = np.meshgrid(np.arange(len(az) - 1), np.arange(ne - 1), indexing="ij")
    a, b = (i * ne + j).ravel(), ((i + 1) * ne + j).ravel()
    c, d = (i * ne + j + 1).ravel(), ((i + 1) * ne + j + 1).ravel()
    faces = np.vstack([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    mesh = trimesh.Trimesh(verts, faces, process=False)
    outward = np.einsum("ij,ij->i", mesh.face_normals, mesh.triangles_center) > 0
    if not outward.all():
        mesh.faces = mesh.faces[:, ::-1]
    return mesh


def sphere_scan(rng, n: int = 50_000, sigma_mm: float = 0.1) -> np.ndarray:
    az = rng.uniform(*np.radians(AZ_DEG), n)
    el = np.arcsin(rng.uniform(*np.sin(np.radians(EL_DEG)), n))  # uniform in area
    return patch_point(az, el, R_MM + rng.normal(0.0, sigma_mm, n))


def wall_cloud(rng, n: int = 50_000, outlier_ratio: float = 0.2, sigma_mm: float = 0.1) -> np.ndarray:
    n_out = int(round(n * outlier_ratio))
    n_in = n - n_out
    inl = np.stack([rng.uniform(-450, 450, n_in), 600 + rng.normal(0, sigma_mm, n_in),
                    rng.uniform(150, 1050, n_in)], axis=1)
    out = np.stack([rng.uniform(-450, 450, n_out), rng.uniform(500, 700, n_out),
                    rng.uniform(150, 1050, n_out)], axis=1)
    return np.vstack([inl, out])[rng.permutation(n)]


def plate_hole_mesh(cell_mm: float = 10.0) -> trimesh.Trimesh:
    xs = np.arange(-200, 200 + cell_mm / 2, cell_mm)
    ys = np.arange(-150, 150 + cell_mm / 2, cell_mm)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    verts = np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], axis=1)
    ny = len(ys)
    faces = []
    for i in range(len(xs) - 1):
        for j in range(ny - 1):
            cx, cy = xs[i] + cell_mm / 2, ys[j] + cell_mm / 2
            if 20 < cx < 100 and -10 < cy < 70:  # the 80 x 80 mm hole
                continue
            a, b, c, d = i * ny + j, (i + 1) * ny + j, i * ny + j + 1, (i + 1) * ny + j + 1
            faces += [[a, b, d], [a, d, c]]  # counter-clockwise seen from +z
    mesh = trimesh.Trimesh(verts, np.array(faces), process=False)
    mesh.remove_unreferenced_vertices()
    return mesh


# ----------------------------------------------------------------------------- multi-face parts (issue 26)

def _grid(fn, nu: int, nv: int, outward):
    """A face tessellated on an (nu+1) x (nv+1) grid of fn(s, t), s, t in 0..1, triangles facing ``outward``."""
    s, t = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="ij")
    verts = fn(s, t).reshape(-1, 3)
    n1 = nv + 1
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
    a, b = (i * n1 + j).ravel(), ((i + 1) * n1 + j).ravel()
    c, d = (i * n1 + j + 1).ravel(), ((i + 1) * n1 + j + 1).ravel()
    faces = np.vstack([np.stack([a, b, d], 1), np.stack([a, d, c], 1)])
    tri = verts[faces]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", n, outward(tri.mean(axis=1))) < 0
    faces[flip] = faces[flip][:, ::-1]
    return verts, faces


def _outline(fn, step_mm: float = 2.0) -> list:
    """The face's outline (its grid's border, s, t in 0..1) sampled about every step_mm, as lists of mm."""
    border = []
    for s0, t0, s1, t1 in ((0, 0, 1, 0), (1, 0, 1, 1), (1, 1, 0, 1), (0, 1, 0, 0)):
        f = np.linspace(0, 1, 2001)
        p = fn(s0 + (s1 - s0) * f, t0 + (t1 - t0) * f)
        length = float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
        k = max(2, int(np.ceil(length / step_mm)) + 1)
        f = np.linspace(0, 1, k)
        border.append(fn(s0 + (s1 - s0) * f, t0 + (t1 - t0) * f))
    pts = np.vstack(border)
    _, keep = np.unique(np.round(pts, 6), axis=0, return_index=True)  # a degenerate edge (a pole) is one point
    return np.round(pts[np.sort(keep)], 4).tolist()


def _plane_face(origin, e1, e2, normal, nu=10, nv=10):
    origin, e1, e2, normal = (np.asarray(x, float) for x in (origin, e1, e2, normal))
    fn = lambda s, t: origin + np.asarray(s)[..., None] * e1 + np.asarray(t)[..., None] * e2  # noqa: E731
    truth = {"model": "plane", "normal": (normal / np.linalg.norm(normal)).tolist(),
             "offset_mm": float(normal @ origin / np.linalg.norm(normal))}
    return fn, nu, nv, (lambda p: np.broadcast_to(normal, p.shape)), truth


def _quad_face(p00, p10, p11, p01, normal, nu=10, nv=4):
    """A planar quadrilateral (bilinear in its corners)."""
    P = [np.asarray(x, float) for x in (p00, p10, p11, p01)]
    normal = np.asarray(normal, float)

    def fn(s, t):
        s, t = np.asarray(s)[..., None], np.asarray(t)[..., None]
        return (1 - s) * (1 - t) * P[0] + s * (1 - t) * P[1] + s * t * P[2] + (1 - s) * t * P[3]

    n = normal / np.linalg.norm(normal)
    truth = {"model": "plane", "normal": n.tolist(), "offset_mm": float(n @ P[0])}
    return fn, nu, nv, (lambda p: np.broadcast_to(normal, p.shape)), truth


def _cylinder_face(center, e1, e2, axis, r, ang, length, concave=False, step_deg=1.0, nv=10):
    c, e1, e2, a = (np.asarray(x, float) for x in (center, e1, e2, axis))

    def fn(s, t):
        u = ang[0] + (ang[1] - ang[0]) * np.asarray(s)
        v = length[0] + (length[1] - length[0]) * np.asarray(t)
        return c + r * (np.cos(u)[..., None] * e1 + np.sin(u)[..., None] * e2) + v[..., None] * a

    def outward(p):
        d = p - c
        d = d - (d @ a)[:, None] * a
        return -d if concave else d

    nu = int(round(np.degrees(ang[1] - ang[0]) / step_deg))
    truth = {"model": "cylinder", "axis": a.tolist(), "axis_point_mm": c.tolist(), "radius_mm": float(r),
             "concave": bool(concave)}
    return fn, nu, nv, outward, truth


def _sphere_face(center, r, el, step_deg=2.0):
    c = np.asarray(center, float)

    def fn(s, t):
        az = 2 * np.pi * np.asarray(s)
        e = el[0] + (el[1] - el[0]) * np.asarray(t)
        return c + r * np.stack([np.cos(e) * np.cos(az), np.cos(e) * np.sin(az), np.sin(e) + 0 * az], axis=-1)

    nu = int(round(360 / step_deg))
    nv = int(round(np.degrees(el[1] - el[0]) / step_deg))
    truth = {"model": "sphere", "center_mm": c.tolist(), "radius_mm": float(r), "concave": False}
    return fn, nu, nv, (lambda p: p - c), truth


def faces_of_part(name: str) -> list:
    """The faces (fn, nu, nv, outward, truth) of a multi-face sample part."""
    if name == "box_open":
        X, Y, H = 150.0, 100.0, 150.0
        return [_plane_face([-X, -Y, H], [2 * X, 0, 0], [0, 2 * Y, 0], [0, 0, 1], 30, 20),
                _plane_face([X, -Y, 0], [0, 2 * Y, 0], [0, 0, H], [1, 0, 0], 20, 15),
                _plane_face([-X, -Y, 0], [0, 2 * Y, 0], [0, 0, H], [-1, 0, 0], 20, 15),
                _plane_face([-X, Y, 0], [2 * X, 0, 0], [0, 0, H], [0, 1, 0], 30, 15),
                _plane_face([-X, -Y, 0], [2 * X, 0, 0], [0, 0, H], [0, -1, 0], 30, 15)]
    if name == "pipe_half":
        L, RO, RI = 150.0, 120.0, 100.0
        ex, ey, ez = np.eye(3)
        ang = (0.0, np.pi)
        faces = [_cylinder_face([0, 0, 0], ey, ez, ex, RO, ang, (-L, L)),
                 _cylinder_face([0, 0, 0], ey, ez, ex, RI, ang, (-L, L), concave=True)]
        for sx in (1.0, -1.0):  # half-ring ends
            def ring(s, t, sx=sx):
                u = np.pi * np.asarray(s)
                rr = RI + (RO - RI) * np.asarray(t)
                return np.stack([sx * L + 0 * u, rr * np.cos(u), rr * np.sin(u)], axis=-1)
            n = np.array([sx, 0.0, 0.0])
            faces.append((ring, 180, 4, (lambda p, n=n: np.broadcast_to(n, p.shape)),
                          {"model": "plane", "normal": n.tolist(), "offset_mm": L}))
        faces += [_plane_face([-L, RI, 0], [2 * L, 0, 0], [0, RO - RI, 0], [0, 0, -1], 30, 4),
                  _plane_face([-L, -RO, 0], [2 * L, 0, 0], [0, RO - RI, 0], [0, 0, -1], 30, 4)]
        return faces
    if name == "dome_cylinder":
        R, H = 100.0, 150.0
        ex, ey, ez = np.eye(3)
        return [_cylinder_face([0, 0, 0], ex, ey, ez, R, (-np.pi, np.pi), (0.0, H), step_deg=2.0, nv=15),
                _sphere_face([0, 0, H], R, (0.0, np.pi / 2))]
    if name == "plate_chamfer":
        X, Y, T, C = 150.0, 100.0, 20.0, 10.0
        top = _plane_face([-(X - C), -(Y - C), T], [2 * (X - C), 0, 0], [0, 2 * (Y - C), 0], [0, 0, 1], 28, 18)
        xa, ya, xb, yb = X - C, Y - C, X, Y
        zt, zb = T, T - C
        chamfers = [
            _quad_face([xa, -ya, zt], [xa, ya, zt], [xb, yb, zb], [xb, -yb, zb], [1, 0, 1]),
            _quad_face([-xa, ya, zt], [-xa, -ya, zt], [-xb, -yb, zb], [-xb, yb, zb], [-1, 0, 1]),
            _quad_face([xa, ya, zt], [-xa, ya, zt], [-xb, yb, zb], [xb, yb, zb], [0, 1, 1]),
            _quad_face([-xa, -ya, zt], [xa, -ya, zt], [xb, -yb, zb], [-xb, -yb, zb], [0, -1, 1]),
        ]
        sides = [_plane_face([X, -Y, 0], [0, 2 * Y, 0], [0, 0, zb], [1, 0, 0], 20, 2),
                 _plane_face([-X, -Y, 0], [0, 2 * Y, 0], [0, 0, zb], [-1, 0, 0], 20, 2),
                 _plane_face([-X, Y, 0], [2 * X, 0, 0], [0, 0, zb], [0, 1, 0], 30, 2),
                 _plane_face([-X, -Y, 0], [2 * X, 0, 0], [0, 0, zb], [0, -1, 0], 30, 2)]
        return [top, *chamfers, *sides]
    raise KeyError(name)


PARTS = ("box_open", "pipe_half", "dome_cylinder", "plate_chamfer")


def part_mesh(name: str) -> tuple[trimesh.Trimesh, list]:
    """The part's mesh (vertices merged) and the truth of its faces (with outlines)."""
    verts, faces, truth, at = [], [], [], 0
    for fn, nu, nv, outward, t in faces_of_part(name):
        v, f = _grid(fn, nu, nv, outward)
        verts.append(v)
        faces.append(f + at)
        at += len(v)
        truth.append({**t, "outline_mm": _outline(fn)})
    mesh = trimesh.Trimesh(np.vstack(verts), np.vstack(faces), process=True)
    return mesh, truth


def part_scan(mesh: trimesh.Trimesh, rng, n: int = 60_000, sigma_mm: float = 0.1):
    """A noisy scan of the mesh: points, and normals estimated from them, oriented out of the material."""
    import open3d as o3d

    pts, face_idx = trimesh.sample.sample_surface(mesh, n, seed=rng)
    pts = np.asarray(pts) + rng.normal(0.0, sigma_mm, (n, 3))
    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=30))
    normals = np.asarray(pc.normals)
    flip = np.einsum("ij,ij->i", normals, mesh.face_normals[face_idx]) < 0
    normals[flip] *= -1
    return pts, normals


def write_ply_with_normals(path: Path, pts: np.ndarray, normals: np.ndarray) -> None:
    """Binary little-endian PLY of float32 x y z nx ny nz."""
    data = np.hstack([pts, normals]).astype("<f4")
    head = ("ply\nformat binary_little_endian 1.0\n"
            f"element vertex {len(data)}\n"
            + "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz"))
            + "end_header\n").encode()
    path.write_bytes(head + data.tobytes())


def write_pipe_step(path: Path) -> None:
    """pipe_half as a STEP solid (OCP): the same six faces as pipe_half.stl, exact B-rep surfaces.

    The header's time stamp is fixed so that the file is the same on every run.
    """
    import contextlib
    import io
    import re

    from OCP.BRepAlgoAPI import BRepAlgoAPI_Cut
    from OCP.BRepPrimAPI import BRepPrimAPI_MakeCylinder
    from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    ax = gp_Ax2(gp_Pnt(-150, 0, 0), gp_Dir(1, 0, 0), gp_Dir(0, 1, 0))  # angle 0 at +y, turning through +z
    outer = BRepPrimAPI_MakeCylinder(ax, 120.0, 300.0, np.pi).Shape()
    inner = BRepPrimAPI_MakeCylinder(ax, 100.0, 300.0, np.pi).Shape()
    writer = STEPControl_Writer()
    with contextlib.redirect_stdout(io.StringIO()):
        writer.Transfer(BRepAlgoAPI_Cut(outer, inner).Shape(), STEPControl_AsIs)
        writer.Write(str(path))
    text = re.sub(r"'\d{4}-\d{2}-\d{2}T\d{2}:\d{2}:\d{2}'", "'2026-12-01T00:00:00'", path.read_text(), count=1)
    path.write_text(text)


def make_parts() -> list[str]:
    """Write every multi-face part (mesh, scan) and faces_truth.json; returns the file names."""
    import json

    rng = np.random.default_rng(20261201)
    names, truth_all = [], {}
    for name in PARTS:
        mesh, truth = part_mesh(name)
        mesh.export(OUT / f"{name}.stl")
        pts, normals = part_scan(mesh, rng)
        write_ply_with_normals(OUT / f"{name}_scan.ply", pts, normals)
        truth_all[name] = {"scan_sigma_mm": 0.1, "faces": truth}
        names += [f"{name}.stl", f"{name}_scan.ply"]
    (OUT / "faces_truth.json").write_text(json.dumps(truth_all) + "\n")
    write_pipe_step(OUT / "pipe_half.step")
    return names + ["faces_truth.json", "pipe_half.step"]


def hood_point(u, v):
    """The hood's skin at (u, v) in [-1, 1]^2 (mm): x along its length, the crown and twist in z."""
    u, v = np.asarray(u, float), np.asarray(v, float)
    x = 350.0 * u
    y = v * (235.0 - 15.0 * u)
    z = 40.0 * (1.0 - u ** 2) * (1.0 - 0.3 * v ** 2) + 15.0 * v ** 3 * (0.5 + 0.5 * u) + 10.0 * u
    return np.stack([x, y, z], axis=-1)


def hood_mesh(cell_mm: float = 5.0) -> trimesh.Trimesh:
    nu, nv = int(700 / cell_mm) + 1, int(470 / cell_mm) + 1
    U, V = np.meshgrid(np.linspace(-1, 1, nu), np.linspace(-1, 1, nv), indexing="ij")
    P = hood_point(U, V).reshape(-1, 3)
    i = (np.arange(nu - 1)[:, None] * nv + np.arange(nv - 1)[None, :]).ravel()
    f = np.vstack([np.stack([i, i + nv, i + 1], 1), np.stack([i + 1, i + nv, i + nv + 1], 1)])
    mesh = trimesh.Trimesh(P, f, process=False)
    if mesh.face_normals[:, 2].mean() < 0:
        mesh.invert()
    return mesh


SHELL_HOLES = ((-120.0, 40.0), (60.0, -90.0))


def shell_point(x, y):
    """The shell's height over (x, y) (mm): the elliptic dome plus the bump."""
    r2 = (x / 250.0) ** 2 + (y / 180.0) ** 2
    return 90.0 * np.sqrt(np.clip(1.0 - r2, 0.0, None)) + 12.0 * np.exp(-((x - 80.0) ** 2 + (y + 40.0) ** 2) / 5000.0)


def shell_scan(rng, n: int = 60_000, sigma_mm: float = 1.0, outlier_ratio: float = 0.005):
    # a fine triangulation of the shell (where z >= 55 mm, outside the holes), sampled area-uniformly
    xs, ys = np.meshgrid(np.linspace(-250, 250, 501), np.linspace(-180, 180, 361), indexing="ij")
    P = np.stack([xs, ys, shell_point(xs, ys)], -1).reshape(-1, 3)
    nx, ny = xs.shape
    i = (np.arange(nx - 1)[:, None] * ny + np.arange(ny - 1)[None, :]).ravel()
    f = np.vstack([np.stack([i, i + ny, i + 1], 1), np.stack([i + 1, i + ny, i + ny + 1], 1)])
    c = P[f].mean(axis=1)
    keep = c[:, 2] >= 55.0
    for hx, hy in SHELL_HOLES:
        keep &= np.hypot(c[:, 0] - hx, c[:, 1] - hy) > 25.0
    mesh = trimesh.Trimesh(P, f[keep], process=False)
    m_in = n - int(round(n * outlier_ratio))
    # Sampled by hand, not by trimesh.sample.sample_surface (as part_scan and the benchmarks do):
    # trimesh draws its random numbers in another order (one cumulative-sum pick, then an (n, 2)
    # block), so it would change the shipped freeform_shell_scan.ply and the programs made from it.
    area = mesh.area_faces
    fi = rng.choice(len(area), m_in, p=area / area.sum())
    a, b = rng.random(m_in), rng.random(m_in)
    flip = a + b > 1
    a[flip], b[flip] = 1 - a[flip], 1 - b[flip]
    t = mesh.triangles[fi]
    pts = t[:, 0] + a[:, None] * (t[:, 1] - t[:, 0]) + b[:, None] * (t[:, 2] - t[:, 0])
    nrm = mesh.face_normals[fi] * np.sign(mesh.face_normals[fi, 2:3])
    pts += rng.normal(0.0, sigma_mm, (m_in, 1)) * nrm
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    out = rng.uniform(lo, hi + [0.0, 0.0, 60.0], (n - m_in, 3))
    pts = np.vstack([pts, out])[rng.permutation(n)]
    # normals as a scanner's software gives them: from 30 neighbours, oriented out of the material (+z)
    import open3d as o3d

    pc = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    pc.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(knn=30))
    normals = np.asarray(pc.normals)
    normals[normals[:, 2] < 0] *= -1
    return pts, normals


def make_freeform() -> list[Path]:
    """Write the free-form parts (issue 46) into samples/ (their jobs run: samples/freeform_hood.toml,
    samples/freeform_shell_scan.toml); returns the paths written."""
    rng = np.random.default_rng(20260046)
    hood_mesh().export(OUT / "freeform_hood.stl")
    write_ply_with_normals(OUT / "freeform_shell_scan.ply", *shell_scan(rng))
    return [OUT / "freeform_hood.stl", OUT / "freeform_shell_scan.ply"]


def main() -> None:
    OUT.mkdir(exist_ok=True)
    rng = np.random.default_rng(20230601)
    sphere_patch_mesh().export(OUT / "sphere_patch.stl")
    trimesh.PointCloud(sphere_scan(rng).astype(np.float32)).export(OUT / "sphere_scan.ply")
    trimesh.PointCloud(wall_cloud(rng).astype(np.float32)).export(OUT / "wall.ply")
    plate_hole_mesh().export(OUT / "plate_hole.stl")
    written = [OUT / name for name in ("sphere_patch.stl", "sphere_scan.ply", "wall.ply", "plate_hole.stl",
                                       *make_parts())] + make_freeform()
    for path in written:
        print(f"wrote {path} ({path.stat().st_size / 1e6:.2f} MB)")


if __name__ == "__main__":
    main()
