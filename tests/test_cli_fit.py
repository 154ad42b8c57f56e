"""``camtool fit``: output, --save, and the bad-input corpus (one line, exit 2)."""
import json
import struct

import numpy as np
import pytest

from camtool.part.surface import load_surface

from conftest import SAMPLES, run_camtool

BAD = __import__("pathlib").Path(__file__).resolve().parent / "bad_input"


def _write_corpus(tmp_path):
    """The corpus: small files committed under tests/bad_input/, plus ones made here."""
    files = {name: BAD / name for name in ("nan.xyz", "two_points.xyz", "collinear.xyz", "huge.xyz",
                                           "notes.docx")}
    files["empty.stl"] = tmp_path / "empty.stl"
    files["empty.stl"].write_bytes(b"")
    tri = struct.pack("<12fH", *([0.0] * 12), 0)
    trunc = tmp_path / "truncated.stl"  # header claims 1000 triangles, holds 3 and a half
    trunc.write_bytes(b"\0" * 80 + struct.pack("<I", 1000) + tri * 3 + tri[:20])
    files["truncated.stl"] = trunc
    noise = tmp_path / "noise.xyz"
    np.savetxt(noise, np.random.default_rng(0).uniform(0, 500, (2000, 3)))
    files["noise.xyz"] = noise
    files["missing.stl"] = tmp_path / "missing.stl"
    folder = tmp_path / "folder.stl"
    folder.mkdir()
    files["folder.stl"] = folder
    return files


CASES = {
    "empty.stl": "empty",
    "truncated.stl": "truncated or corrupt",
    "nan.xyz": "NaN or infinite",
    "two_points.xyz": "needs at least 3",
    "collinear.xyz": "line",
    "noise.xyz": "min_inlier_ratio",
    "notes.docx": "unsupported file type",
    "missing.stl": "not found",
    "folder.stl": "folder",
    "huge.xyz": "not a workpiece",
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_input_one_line_exit_2(cli, tmp_path, name):
    path = _write_corpus(tmp_path)[name]
    r = cli("fit", path)
    assert r.exit_code == 2, r.output
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camtool: error: ")
    assert CASES[name] in lines[0] and path.name in lines[0]
    assert "Traceback" not in r.output


def test_fit_json_and_save(cli, tmp_path):
    out = tmp_path / "surface.json"
    r = cli("fit", SAMPLES / "plate_hole.stl", "--json", "--save", out)
    assert r.exit_code == 0, r.output
    d = json.loads(r.stdout)
    assert d["model"] == "plane" and np.allclose(d["normal"], [0, 0, 1]) and abs(d["offset_mm"]) < 1e-9
    assert d["boundary"]["uv_unit"] == "mm" and len(d["boundary"]["holes_uv"]) == 1
    assert {"inlier_ratio", "rms_mm", "max_residual_mm", "n_points"} <= set(d)
    s = load_surface(out)
    assert s.model == "plane" and len(s.boundary.holes_uv) == 1


def test_fit_sphere_scan_human_output(cli):
    r = cli("fit", SAMPLES / "sphere_scan.ply", "--model", "sphere", "--seed", "1")
    assert r.exit_code == 0, r.output
    rows = dict(line.split(None, 1) for line in r.stdout.strip().splitlines())
    assert abs(float(rows["radius_mm"]) - 600.0) < 0.05
    assert rows["model"] == "sphere" and "deg" in rows["boundary"]


def test_units_warning_goes_to_stderr(cli, tmp_path):
    path = tmp_path / "wall_m.xyz"
    rng = np.random.default_rng(0)
    np.savetxt(path, np.column_stack([rng.uniform(-0.4, 0.4, 3000), np.full(3000, 0.6), rng.uniform(0.2, 1, 3000)]))
    r = cli("fit", path, "--json")
    assert r.exit_code == 0 and 'units = "m"' in r.stderr
    assert abs(json.loads(r.stdout)["offset_mm"]) == pytest.approx(0.6, abs=1e-6)
    r = cli("fit", path, "--units", "m", "--json")
    assert r.stderr == "" and abs(json.loads(r.stdout)["offset_mm"]) == pytest.approx(600.0, abs=1e-3)


def test_subprocess_exit_code():
    r = run_camtool("fit", BAD / "notes.docx")
    assert r.returncode == 2 and r.stderr.count("\n") == 1
