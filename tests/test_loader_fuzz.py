"""Seeded, time-bounded fuzz of the workpiece loaders.

Small valid files (PLY clouds and meshes, ASCII and binary; XYZ; PCD ASCII and
binary; STL ASCII and binary; OBJ; OFF) are generated, mutated (cut at a random offset, random bytes
flipped, a number replaced by nan / inf / 1e-300 / 1e300, a line dropped or
doubled) and loaded. Every outcome must be

- a BadInput (camtool.errors) with a one-line message naming the file, or
- a Workpiece whose points are all finite and are what the file really holds:
  for clouds exactly the rows an independent strict parse of the mutated file
  finds (so no point is made up, zero-filled or lost); for meshes the triangle
  count of that parse (STL, PLY, OFF), and sampled points inside the box of the
  file's vertices (the data sit far from the origin, so zero-filled vertices
  show).

Never another exception, and nothing printed on stdout or stderr.
"""
from __future__ import annotations

import re
import struct
import time

import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.part.workpiece import TINY_COORDINATE, load_workpiece

SEED = 20240611
TIME_BUDGET_S = 12.0  # the whole test stays well below 30 s
MAX_CASES = 4000
OFFSET = np.array([500.0, 600.0, 700.0])  # far from the origin: zero-filled points cannot hide


# --------------------------------------------------------------------------- valid files

def _cloud(rng, n=40):
    pts = OFFSET + rng.uniform(-80, 80, (n, 3))
    nrm = rng.normal(size=(n, 3))
    return pts, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


def _ply_ascii(pts):
    head = (f"ply\nformat ascii 1.0\nelement vertex {len(pts)}\n"
            "property double x\nproperty double y\nproperty double z\nend_header\n")
    return (head + "".join(f"{p[0]:.6f} {p[1]:.6f} {p[2]:.6f}\n" for p in pts)).encode()


def _ply_binary(pts, nrm):
    head = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(pts)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            "property float nx\nproperty float ny\nproperty float nz\nend_header\n")
    return head.encode() + np.hstack([pts, nrm]).astype("<f4").tobytes()


def _xyz(pts):
    return "".join(f"{p[0]:.5f} {p[1]:.5f} {p[2]:.5f}\n" for p in pts).encode()


def _pcd(pts, binary):
    head = (f"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
            f"WIDTH {len(pts)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {len(pts)}\n")
    if binary:
        return (head + "DATA binary\n").encode() + pts.astype("<f4").tobytes()
    return (head + "DATA ascii\n" + "".join(f"{p[0]:.4f} {p[1]:.4f} {p[2]:.4f}\n" for p in pts)).encode()


def _mesh():
    m = trimesh.creation.icosphere(subdivisions=1, radius=80.0)
    m.apply_translation(OFFSET)
    return m


def _as_bytes(data):
    return data if isinstance(data, bytes) else data.encode()


def base_files(rng):
    """name -> (bytes, kind); kind tells the reference parser what the file is."""
    pts, nrm = _cloud(rng)
    mesh = _mesh()
    return {
        "ascii.ply": (_ply_ascii(pts), "ply_cloud"),
        "binary.ply": (_ply_binary(pts, nrm), "ply_cloud"),
        "cloud.xyz": (_xyz(pts), "xyz"),
        "ascii.pcd": (_pcd(pts, False), "pcd"),
        "binary.pcd": (_pcd(pts, True), "pcd"),
        "binary.stl": (_as_bytes(mesh.export(file_type="stl")), "stl"),
        "ascii.stl": (_as_bytes(mesh.export(file_type="stl_ascii")), "stl"),
        "mesh.obj": (_as_bytes(mesh.export(file_type="obj")), "obj"),
        "mesh_ascii.ply": (_as_bytes(mesh.export(file_type="ply", encoding="ascii")), "ply_mesh"),
        "mesh_binary.ply": (_as_bytes(mesh.export(file_type="ply")), "ply_mesh"),
        "mesh.off": (_as_bytes(mesh.export(file_type="off")), "off"),
    }


# --------------------------------------------------------------------------- mutations

_TOKENS = [b"nan", b"-inf", b"inf", b"1e-300", b"NaN", b"1e300", b"-0", b"x", b""]
_NUMBER = re.compile(rb"-?\d+\.?\d*(?:e-?\d+)?")


def mutate(data: bytes, rng) -> tuple[bytes, str]:
    """One random mutation of ``data`` and a description of it."""
    kind = rng.integers(6)
    if kind == 0:  # cut short
        k = int(rng.integers(1, len(data)))
        return data[:k], f"truncated at {k}"
    if kind == 1:  # flip bytes
        b = bytearray(data)
        spots = rng.integers(0, len(b), int(rng.integers(1, 4)))
        for i in spots:
            b[i] = int(rng.integers(256))
        return bytes(b), f"bytes changed at {sorted(int(i) for i in spots)}"
    if kind == 2:  # a number replaced by a special token (text) or a special float (binary)
        numbers = list(_NUMBER.finditer(data))
        if numbers and data.count(b"\0") == 0:
            m = numbers[int(rng.integers(len(numbers)))]
            tok = _TOKENS[int(rng.integers(len(_TOKENS)))]
            return data[:m.start()] + tok + data[m.end():], f"number at {m.start()} -> {tok!r}"
        special = [np.nan, np.inf, -np.inf, 1e-40, 1e-300, 1e30]
        v = special[int(rng.integers(len(special)))]
        at = int(rng.integers(0, max(1, len(data) - 4)))
        return data[:at] + struct.pack("<f", v) + data[at + 4:], f"float32 {v} at {at}"
    lines = data.split(b"\n")
    i = int(rng.integers(len(lines)))
    if kind == 3:  # drop a line
        return b"\n".join(lines[:i] + lines[i + 1:]), f"line {i + 1} dropped"
    if kind == 4:  # double a line
        return b"\n".join(lines[:i + 1] + lines[i:]), f"line {i + 1} doubled"
    k = int(rng.integers(1, len(data)))  # cut and append a stray line
    return data[:k] + b"\n1 2\n", f"cut at {k}, stray line appended"


# --------------------------------------------------------------------------- reference parsers
# Small strict readers written for this test: they say what a mutated file really
# holds, or None when the file is not a valid file of its format.

def _floats(tokens):
    try:
        return [float(t) for t in tokens]
    except ValueError:
        return None


def ref_ply_cloud(data: bytes):
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        return None
    try:
        head = data[:end].decode("ascii").split("\n")[1:]
    except UnicodeDecodeError:
        return None
    fmt, count, props = None, None, []
    for line in head:
        t = line.split()
        if not t or t[0] == "comment":
            continue
        if t[0] == "format" and len(t) == 3:
            fmt = t[1]
        elif t[0] == "element" and len(t) == 3 and t[1] == "vertex" and t[2].isdigit() and count is None:
            count = int(t[2])
        elif t[0] == "property" and len(t) == 3 and t[1] in ("float", "double") and count is not None:
            props.append((t[2], "<f4" if t[1] == "float" else "<f8"))
        else:
            return None
    names = [p[0] for p in props]
    if count is None or names[:3] != ["x", "y", "z"] or len(set(names)) != len(names):
        return None
    body = data[end + len(b"end_header\n"):]
    if fmt == "ascii":
        try:
            lines = body.decode("utf-8").splitlines()
        except UnicodeDecodeError:
            return None
        rows = [_floats(ln.split()) for ln in lines[:count]]
        if len(rows) != count or any(r is None or len(r) != len(props) for r in rows):
            return None
        if any(ln.strip() for ln in lines[count:]):
            return None
        table = np.array(rows, dtype=float).reshape(count, len(props))
        return np.column_stack([table[:, k].astype(props[k][1]).astype(float) for k in range(3)])
    if fmt == "binary_little_endian":
        dt = np.dtype([(n, t) for n, t in props])
        if len(body) != count * dt.itemsize:
            return None
        rec = np.frombuffer(body, dtype=dt)
        return np.column_stack([rec[c].astype(float) for c in "xyz"])
    return None


def ref_ply_mesh(data: bytes):
    """(vertices, triangle count) of a PLY laid out as trimesh writes it, or None."""
    end = data.find(b"end_header\n")
    if not data.startswith(b"ply\n") or end < 0:
        return None
    try:
        head = [ln.split() for ln in data[:end].decode("ascii").split("\n")[1:]]
    except UnicodeDecodeError:
        return None
    head = [t for t in head if t and t[0] != "comment"]
    if len(head) != 7 or len(head[0]) != 3 or head[0][:1] != ["format"]:
        return None
    fmt = head[0][1]
    if not (head[1][:2] == ["element", "vertex"] and len(head[1]) == 3 and head[1][2].isdigit()
            and head[2:5] == [["property", "float", c] for c in "xyz"]
            and head[5][:2] == ["element", "face"] and len(head[5]) == 3 and head[5][2].isdigit()
            and head[6][:4] == ["property", "list", "uchar", "int"] and len(head[6]) == 5):
        return None
    nv, nf = int(head[1][2]), int(head[5][2])
    body = data[end + len(b"end_header\n"):]
    if fmt == "ascii":
        try:
            lines = body.decode("utf-8").splitlines()
        except UnicodeDecodeError:
            return None
        verts = [_floats(ln.split()) for ln in lines[:nv]]
        faces = [_floats(ln.split()) for ln in lines[nv:nv + nf]]
        if len(verts) != nv or any(v is None or len(v) != 3 for v in verts):
            return None
        if len(faces) != nf or any(f is None or len(f) != 4 or f[0] != 3 for f in faces):
            return None
        if any(ln.strip() for ln in lines[nv + nf:]):
            return None
        verts = np.array(verts, dtype=float).reshape(-1, 3).astype("<f4").astype(float)
        idx = np.array([f[1:] for f in faces]).reshape(-1, 3)
    elif fmt == "binary_little_endian":
        if len(body) != 12 * nv + 13 * nf:
            return None
        verts = np.frombuffer(body[:12 * nv], dtype="<f4").reshape(-1, 3).astype(float)
        rec = np.frombuffer(body[12 * nv:], dtype=np.dtype([("n", "u1"), ("i", "<3i4")]))
        if (rec["n"] != 3).any():
            return None
        idx = rec["i"]
    else:
        return None
    if len(idx) and (idx.min() < 0 or idx.max() >= nv or (idx != np.round(idx)).any()):
        return None
    return verts, nf


def ref_off(data: bytes):
    """(vertices, triangle count) of an OFF of triangles (extra tokens are colours), or None."""
    lines = [ln.split("#", 1)[0].strip() for ln in data.decode("utf-8", errors="replace").splitlines()]
    lines = [ln for ln in lines if ln]
    if len(lines) < 2 or lines[0] != "OFF":
        return None
    counts = lines[1].split()
    if len(counts) != 3 or not all(c.isdigit() for c in counts):
        return None
    nv, nf = int(counts[0]), int(counts[1])
    rows = [_floats(ln.split()) for ln in lines[2:2 + nv]]
    if len(rows) != nv or any(r is None or len(r) < 3 for r in rows):
        return None
    faces = [ln.split() for ln in lines[2 + nv:]]
    if len(faces) != nf or any(f[0] != "3" or len(f) < 4 for f in faces):
        return None
    try:
        idx = np.array([[int(t) for t in f[1:4]] for f in faces]).reshape(-1, 3)
    except ValueError:
        return None
    if len(idx) and (idx.min() < 0 or idx.max() >= nv):
        return None
    return np.array([r[:3] for r in rows], dtype=float).reshape(-1, 3), nf


def ref_xyz(data: bytes):
    text = data.decode("utf-8", errors="replace")
    rows = [ln for ln in text.replace(",", " ").replace(";", " ").splitlines()
            if ln.strip() and not ln.lstrip().startswith(("#", "//"))]
    if rows and all(_floats([t]) is None for t in rows[0].split()):
        rows = rows[1:]  # a header line: words only
    if rows and len(rows[0].split()) == 1:
        t = rows[0].split()[0]
        v = _floats([t])
        if v is not None and np.isfinite(v[0]) and v[0] >= 0 and v[0] == int(v[0]):
            if int(v[0]) != len(rows) - 1:
                return None
            rows = rows[1:]
    parsed = [_floats(r.split()) for r in rows]
    if not parsed or any(p is None or len(p) != len(parsed[0]) for p in parsed) or len(parsed[0]) < 3:
        return None
    return np.array(parsed)[:, :3]


def ref_pcd(data: bytes):
    at = data.find(b"DATA ")
    nl = data.find(b"\n", at)
    if at < 0 or nl < 0:
        return None
    head = data[:at].decode("ascii", errors="replace").splitlines()  # comments may hold any bytes
    kind = data[at + 5:nl].decode("ascii", errors="replace").strip()
    h = {}
    for line in head:
        t = line.split()
        if t and not t[0].startswith("#"):
            h[t[0]] = t[1:]
    if (h.get("FIELDS") != ["x", "y", "z"] or h.get("SIZE") != ["4"] * 3 or h.get("TYPE") != ["F"] * 3
            or h.get("COUNT", ["1"] * 3) != ["1"] * 3):
        return None
    try:
        w, hh, n = int(h["WIDTH"][0]), int(h.get("HEIGHT", ["1"])[0]), int(h["POINTS"][0])
    except (KeyError, ValueError, IndexError):
        return None
    if w * hh != n or n < 0:
        return None
    body = data[nl + 1:]
    if kind == "binary":
        if len(body) != 12 * n:
            return None
        return np.frombuffer(body, dtype="<f4").reshape(n, 3).astype(float)
    if kind == "ascii":
        try:
            rows = [ln for ln in body.decode("utf-8").splitlines() if ln.strip()]
        except UnicodeDecodeError:
            return None
        parsed = [_floats(r.split()) for r in rows]
        if len(parsed) != n or any(p is None or len(p) != 3 for p in parsed):
            return None
        return np.array(parsed, dtype=float).reshape(n, 3)
    return None


def ref_stl(data: bytes):
    """(vertices, triangle count) or None."""
    if len(data) >= 84:
        n = struct.unpack("<I", data[80:84])[0]
        if len(data) == 84 + 50 * n:
            rec = np.frombuffer(data[84:], dtype=np.dtype([("n", "<3f4"), ("v", "<9f4"), ("a", "<u2")]))
            return rec["v"].reshape(-1, 3).astype(float), n
    text = data.decode("utf-8", errors="replace").lower()
    end = text.rfind("endsolid")
    if not text.lstrip().startswith("solid") or end < 0:
        return None
    facets = len(re.findall(r"(?<!end)facet\b", text))
    if re.search(r"(?<!end)facet\b", text[end:]):
        return None
    verts = [_floats(m.split()) for m in re.findall(r"vertex([^\n]*)", text)]
    if any(v is None or len(v) != 3 for v in verts) or len(verts) != 3 * facets:
        return None
    return np.array(verts, dtype=float).reshape(-1, 3), facets


def ref_obj(data: bytes):
    """The vertices of the ``v`` lines (None if one is malformed)."""
    verts = []
    for line in data.decode("utf-8", errors="replace").splitlines():
        t = line.split()
        if t and t[0] == "v":
            v = _floats(t[1:])
            if v is None or len(v) not in (3, 4, 6, 7):
                return None
            verts.append(v[:3])
    return np.array(verts, dtype=float).reshape(-1, 3)


# --------------------------------------------------------------------------- the oracle

def _usable(values: np.ndarray) -> np.ndarray:
    a = np.abs(values)
    return np.isfinite(values).all(axis=1) & ~((a > 0) & (a < TINY_COORDINATE)).any(axis=1)


def check_outcome(path, data: bytes, kind: str, what: str):
    try:
        wp = load_workpiece(path, sample_points=200, normal_neighbours=5)
    except BadInput as exc:
        msg = str(exc)
        assert msg and "\n" not in msg, f"{what}: BadInput message is not one line: {msg!r}"
        assert msg.startswith(str(path)), f"{what}: BadInput does not name the file: {msg!r}"
        return "bad"
    except Exception as exc:  # noqa: BLE001  (the point of the test)
        pytest.fail(f"{path.name}, {what}: {type(exc).__name__}: {exc}")
    assert np.isfinite(wp.points_mm).all(), f"{what}: non-finite points accepted"
    if kind in ("ply_cloud", "xyz", "pcd"):
        ref = {"ply_cloud": ref_ply_cloud, "xyz": ref_xyz, "pcd": ref_pcd}[kind](data)
        assert ref is not None, f"{path.name}, {what}: accepted a file the strict reference parser rejects"
        assert _usable(ref).all(), f"{path.name}, {what}: accepted NaN, infinite or damaged values"
        assert wp.n_points == len(ref), f"{path.name}, {what}: {wp.n_points} points, the file holds {len(ref)}"
        assert np.allclose(wp.points_mm, ref, rtol=1e-6, atol=1e-9), f"{path.name}, {what}: points differ from the file"
        return "ok"
    if kind in ("stl", "ply_mesh", "off"):
        ref = {"stl": ref_stl, "ply_mesh": ref_ply_mesh, "off": ref_off}[kind](data)
        assert ref is not None, f"{path.name}, {what}: accepted a file the strict reference parser rejects"
        verts, n_tri = ref
        # the mesh repair drops degenerate triangles, saying how many of how many in one warning line
        said = [re.search(r"(\d+) of (\d+) triangles are degenerate", w) for w in wp.warnings]
        dropped = sum(int(m.group(1)) for m in said if m and int(m.group(2)) == n_tri)
        assert len(wp.faces) == n_tri - dropped, \
            f"{path.name}, {what}: {len(wp.faces)} triangles, the file holds {n_tri} ({dropped} said dropped)"
    else:
        verts = ref_obj(data)
        assert verts is not None, f"{path.name}, {what}: accepted malformed vertex lines"
    verts = verts[_usable(verts)]
    lo, hi = verts.min(axis=0), verts.max(axis=0)
    tol = 1e-6 * (1 + np.abs(hi - lo).max())
    inside = ((wp.points_mm >= lo - tol) & (wp.points_mm <= hi + tol)).all()
    assert inside, f"{path.name}, {what}: sampled points outside the file's vertices (made-up geometry)"
    return "ok"


def test_loaders_survive_mutations(tmp_path, capfd):
    rng = np.random.default_rng(SEED)
    files = base_files(rng)
    for name, (data, kind) in files.items():  # the unmutated files load
        path = tmp_path / name
        path.write_bytes(data)
        assert check_outcome(path, data, kind, "unmutated") == "ok", name
    outcomes = {"ok": 0, "bad": 0}
    names = sorted(files)
    deadline = time.monotonic() + TIME_BUDGET_S
    case = 0
    while case < MAX_CASES and time.monotonic() < deadline:
        name = names[case % len(names)]
        data, kind = files[name]
        mutated, what = mutate(data, rng)
        path = tmp_path / f"case{case:04d}_{name}"
        path.write_bytes(mutated)
        outcomes[check_outcome(path, mutated, kind, f"case {case}: {what}")] += 1
        path.unlink()
        case += 1
    out, err = capfd.readouterr()
    assert out == "", f"loaders printed on stdout: {out[:300]!r}"
    assert err == "", f"loaders printed on stderr: {err[:300]!r}"
    assert case >= 8 * len(names), f"only {case} cases ran in {TIME_BUDGET_S} s"
    assert outcomes["bad"] > 0 and outcomes["ok"] > 0, outcomes
    print("FUZZ", case, outcomes)
