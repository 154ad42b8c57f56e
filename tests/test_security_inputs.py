"""A hostile cell, second round (issue #49): inputs opened once, read from that descriptor, and every
malformed value one line. Each test fails without its fix; a hang shows as a subprocess timeout."""
from __future__ import annotations

import io
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest

from camtool import safe_io
from camtool.errors import BadInput

from conftest import ROOT, SAMPLES

ENV = {**os.environ, "PYTHONPATH": str(ROOT)}


def _script(code: str, timeout: float = 30) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout,
                          env=ENV, cwd=ROOT)


def _one_line(exc: BadInput, expect: str = "") -> str:
    text = str(exc)
    assert "\n" not in text and expect in text, text
    return text


# ---------------------------------------------------------------- races: checked, then opened again by name

SWAP = """
import os, sys
from pathlib import Path
target = Path(sys.argv[1]) if len(sys.argv) > 1 else None
def swap(path):
    os.rename(path, str(path) + ".old")
    os.mkfifo(path)
"""


def test_a_urdf_swapped_for_a_fifo_after_its_check_is_never_reopened(tmp_path):
    src = ROOT / "camtool/robots/data/ros-industrial/kuka_kr16_support/urdf/kr16_2.urdf"
    urdf = tmp_path / "r.urdf"
    urdf.write_bytes(src.read_bytes())
    r = _script(SWAP + f"""
import camtool.robots.urdf as U
orig = U.check_urdf
def check_then_swap(path, *a):
    text = orig(path, *a)
    swap(path)
    return text
U.check_urdf = check_then_swap
robot = U.robot_from_urdf(Path({str(urdf)!r}))
print("dof", len(robot.joint_names))
""", timeout=20)
    assert r.returncode == 0 and "dof 6" in r.stdout, r.stderr


def test_a_fifo_as_controller_urdf_is_refused_at_load(tmp_path):
    from camtool.robots import get_robot

    text = (ROOT / "camtool/robots/data/kr16.toml").read_text()
    text = text.replace('file = "ros-industrial/kuka_kr16_support/urdf/kr16_2.urdf"', 'file = "pipe.urdf"')
    (tmp_path / "kr16.toml").write_text(text)
    os.mkfifo(tmp_path / "pipe.urdf")
    with pytest.raises(BadInput) as err:
        get_robot(str(tmp_path / "kr16.toml"))
    _one_line(err.value, "FIFO")


@pytest.mark.parametrize("sample, ext", [("sphere_patch.stl", ".stl"), ("pipe_half.step", ".step")])
def test_a_workpiece_swapped_for_a_fifo_after_its_check_is_read_from_the_checked_descriptor(tmp_path, sample, ext):
    wp = tmp_path / f"part{ext}"
    wp.write_bytes((SAMPLES / sample).read_bytes())
    r = _script(SWAP + f"""
import camtool.part.workpiece as W
orig = W.LOADERS[{ext!r}]
def swap_then_load(path):
    swap(path)        # after load_workpiece checked it: the loader and its library must not reopen the name
    return orig(path)
W.LOADERS[{ext!r}] = swap_then_load
wp = W.load_workpiece(Path({str(wp)!r}), sample_points=500)
print("points", wp.n_points)
""", timeout=40)
    assert r.returncode == 0 and "points" in r.stdout, r.stderr[-2000:]


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    return buf.getvalue()


def _inflating_npz(name="values_um", claim=(1 << 30,)) -> bytes:
    """An .npz whose array header claims 8 GB while the archive holds a few bytes."""
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": claim})
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("u.npy", _npy(np.linspace(0, 1, 3)))
        z.writestr("v.npy", _npy(np.linspace(0, 1, 3)))
        z.writestr(f"{name}.npy", header.getvalue() + b"\0" * 64)
    return buf.getvalue()


def _npy(a) -> bytes:
    b = io.BytesIO()
    np.save(b, a)
    return b.getvalue()


def test_target_removal_file_is_read_once_and_its_inflation_capped(tmp_path):
    from camtool.process.dwell import load_target
    from camtool.process.grid import MapGrid

    grid = MapGrid.__new__(MapGrid)
    f = tmp_path / "target.npz"
    f.write_bytes(_inflating_npz())
    with pytest.raises(BadInput) as err:
        load_target(f, grid)
    _one_line(err.value, "inflates")
    fifo = tmp_path / "fifo.npz"
    os.mkfifo(fifo)
    with pytest.raises(BadInput) as err:
        load_target(fifo, grid)
    _one_line(err.value, "FIFO")


def test_report_json_is_never_reread_from_the_output_folder(tmp_path, monkeypatch):
    """pipeline.run_job took the placed OUT/report.json again by name (a FIFO renamed over it blocked)."""
    import camtool.run.pipeline as P

    src = Path(P.__file__).read_text()
    assert 'outdir / "report.json").read_text' not in src and "open(" not in src


def test_design_cache_is_read_through_safe_io(tmp_path):
    from camtool.design.objectives import DesignProblem as Evaluator

    ev = Evaluator.__new__(Evaluator)
    ev.cache_file = tmp_path / "cache.json"
    ev.cache = {}
    ev.fingerprint = lambda: "f"
    ev.cache_file.write_text("[1, 2]")
    ev._load_cache()             # a JSON list: not a cache, ignored (was AttributeError)
    assert ev.cache == {}
    ev.cache_file.write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(BadInput) as err:
        ev._load_cache()
    _one_line(err.value, "nested")
    ev.cache_file.write_text(json.dumps({"fingerprint": "f", "entries": {"1,2": [1]}}))
    with pytest.raises(BadInput):
        ev._load_cache()
    ev.cache_file.unlink()
    os.mkfifo(ev.cache_file)
    with pytest.raises(BadInput) as err:
        ev._load_cache()
    _one_line(err.value, "FIFO")


# ---------------------------------------------------------------- stage files: hostile values

def _joint_path(n=4, dof=6):
    from camtool.trajectory import JointPath

    z = np.zeros(n)
    b = np.zeros(n, bool)
    return JointPath(q=np.zeros((n, dof)), path_index=np.arange(n), zone=np.zeros(n, int), position_error_mm=z,
                     orientation_error_rad=z, jump=b, reverse_planned=b, retract=b, singular=b, reached=~b)


def _stage_bytes(header: dict | str | None, arrays: dict) -> bytes:
    extra = {} if header is None else {"header": np.array(header if isinstance(header, str) else json.dumps(header))}
    return _npz(**extra, **arrays)


def _good_stage(tmp_path):
    from camtool.run.stage_files import save_stage

    f = save_stage(_joint_path(), tmp_path / "good.npz")
    with np.load(f) as d:
        arrays = {k: d[k] for k in d.files}
    header = json.loads(str(arrays.pop("header")))
    return header, arrays


def _damaged_stages(tmp_path):
    header, arrays = _good_stage(tmp_path)
    n = len(arrays["q"])
    cases = {
        "q_strings": (header, {**arrays, "q": np.full((n, 6), "x")}),
        "q_complex": (header, {**arrays, "q": np.zeros((n, 6), complex)}),
        "deep_header": ("[" * 50_000 + "]" * 50_000, arrays),
        "header_list": ("[1, 2]", arrays),
        "header_number": ("7", arrays),
        "fields_list": ({**header, "fields": [1]}, arrays),
        "kind_list": ({**header, "kind": ["JointPath"]}, arrays),
        "version_list": ({**header, "version": [1]}, arrays),
        "bad_dtype": ({**header, "fields": {**header["fields"], "q": {"__array__": [[1]], "dtype": "object"}}},
                      {k: v for k, v in arrays.items() if k != "q"}),
        "huge_dtype": ({**header, "fields": {**header["fields"], "q": {"__array__": [[1]], "dtype": "V1000000000"}}},
                       {k: v for k, v in arrays.items() if k != "q"}),
        "deep_field": ({**header, "fields": {**header["fields"], "events": json.loads("[" * 60 + "]" * 60)}}, arrays),
        "no_header": (None, arrays),
    }
    out = {name: _stage_bytes(h, a) for name, (h, a) in cases.items()}
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr("header.npy", _npy(np.array(json.dumps(header))))
        hdr = io.BytesIO()
        np.lib.format.write_array_header_1_0(hdr, {"descr": "<f8", "fortran_order": False, "shape": (1 << 28, 4)})
        z.writestr("q.npy", hdr.getvalue() + b"\0" * 64)
    out["inflates_8gb"] = buf.getvalue()
    return out


@pytest.mark.parametrize("name", ["q_strings", "q_complex", "deep_header", "header_list", "header_number",
                                  "fields_list", "kind_list", "version_list", "bad_dtype", "huge_dtype",
                                  "deep_field", "no_header", "inflates_8gb"])
def test_hostile_stage_files_are_one_line(tmp_path, name):
    from camtool.run.stage_files import load_stage

    f = tmp_path / f"{name}.npz"
    f.write_bytes(_damaged_stages(tmp_path)[name])
    try:
        load_stage(f)
    except BadInput as exc:
        _one_line(exc, str(f))
    else:  # a deep but valid events table may load: only never an internal error
        assert name in ("deep_field",), name


def test_load_npz_caps_what_an_archive_inflates_to():
    with pytest.raises(BadInput) as err:
        safe_io.load_npz(_inflating_npz(), "x.npz", 200 << 20)
    _one_line(err.value, "inflates")
    assert set(safe_io.load_npz(_npz(a=np.arange(3)), "x.npz", 1 << 20)) == {"a"}


def test_load_json_refuses_deep_nesting_without_recursion():
    with pytest.raises(BadInput) as err:
        safe_io.load_json("[" * 200_000 + "]" * 200_000, "deep.json")
    _one_line(err.value, "nested")
    assert safe_io.load_json('{"a": "[[[[["}', "ok.json") == {"a": "[[[[["}


# ---------------------------------------------------------------- robots: bounds a real robot meets

@pytest.mark.parametrize("key, value", [("velocity", 1e-9), ("acceleration", 1e30), ("jerk", 1e-12),
                                        ("lower", -1e9), ("upper", 1e9)])
def test_absurd_but_finite_robot_limits_are_refused_at_load(tmp_path, key, value):
    from camtool.robots import get_robot

    text = (ROOT / "camtool/robots/data/irb2400.toml").read_text()
    lines = text.splitlines()
    i = next(k for k, line in enumerate(lines) if line.split("=")[0].strip() == key)
    lines[i] = f"{key} = {value!r}"
    (tmp_path / "r.toml").write_text("\n".join(lines) + "\n")
    with pytest.raises(BadInput) as err:
        get_robot(str(tmp_path / "r.toml"))
    _one_line(err.value, "joint 1")


def test_every_shipped_robot_meets_the_bounds():
    from camtool.robots import BUILTIN_ROBOTS, get_robot

    for name in BUILTIN_ROBOTS:
        get_robot(name)


# ---------------------------------------------------------------- planted files in -o, surfaces

DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize("name", [".camtool-manifest.json", ".camtool-programs.json", "summary.json",
                                  ".camtool-cache.json"])
def test_planted_deep_json_in_the_output_folder_is_never_an_internal_error(tmp_path, name):
    from camtool.batch.cache import read_manifest
    from camtool.batch.watch import _read_entries
    from camtool.run.output import _manifest, forget_previous

    out = tmp_path / "out"
    out.mkdir()
    (out / name).write_text(DEEP)
    (out / "report.json").write_text(DEEP)
    assert safe_io.read_own_json(out / name) is None
    assert _manifest(out) == [] and _read_entries(out / name) == []
    assert read_manifest(out) is None
    if name == "summary.json":  # a deep summary vouches for nothing: report.json there is foreign
        with pytest.raises(BadInput):
            safe_io.check_outdir(out)
    forget_previous(out)


def test_a_deep_surface_file_is_one_line(tmp_path):
    from camtool.part.surface import load_surface

    f = tmp_path / "surface.json"
    f.write_text('{"format": "camtool-surface", "version": 1, "boundary": ' + DEEP + "}")
    with pytest.raises(BadInput) as err:
        load_surface(f)
    _one_line(err.value, "nested")


def test_a_surface_with_a_huge_boundary_is_refused_at_once(tmp_path):
    import time

    from camtool.part.surface import load_surface

    n = 400_000
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    d = {"format": "camtool-surface", "version": 1, "model": "plane", "origin_mm": [0, 0, 0], "normal": [0, 0, 1],
         "u_axis": [1, 0, 0], "v_axis": [0, 1, 0],
         "boundary": {"outer_uv": np.column_stack([100 * np.cos(t), 100 * np.sin(t)]).round(3).tolist(),
                      "holes_uv": []}}
    f = tmp_path / "surface.json"
    f.write_text(json.dumps(d))
    t0 = time.monotonic()
    with pytest.raises(BadInput) as err:
        load_surface(f)
    _one_line(err.value, "vertices")
    assert time.monotonic() - t0 < 10
