"""A .gltf's side buffers are read through safe_io: a plain file beside it, never a link, a FIFO or a
path out of its folder."""
import json
import os

import numpy as np
import pytest
import trimesh

from camtool.errors import BadInput
from camtool.part.workpiece import load_workpiece


def _write_gltf(folder, name="part.gltf"):
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=50.0)
    files = trimesh.exchange.gltf.export_gltf(trimesh.Scene(mesh))
    for key, data in files.items():
        (folder / (name if key == "model.gltf" else key)).write_bytes(data)
    return folder / name, mesh


def _buffer_uri(gltf):
    return json.loads(gltf.read_text())["buffers"][0]["uri"]


def test_a_gltf_with_its_buffer_beside_it_loads(tmp_path):
    gltf, mesh = _write_gltf(tmp_path)
    wp = load_workpiece(gltf, units="mm", sample_points=500)
    assert np.allclose(np.sort(wp.vertices_mm, axis=0), np.sort(mesh.vertices, axis=0), atol=1e-4)


def test_a_buffer_outside_the_folder_is_refused(tmp_path):
    (tmp_path / "in").mkdir()
    gltf, _ = _write_gltf(tmp_path / "in")
    uri = _buffer_uri(gltf)
    os.rename(tmp_path / "in" / uri, tmp_path / uri)
    gltf.write_text(gltf.read_text().replace(f'"{uri}"', f'"../{uri}"'))
    with pytest.raises(BadInput, match="buffer outside its own folder"):
        load_workpiece(gltf, units="mm", sample_points=500)


def test_a_buffer_that_is_a_link_or_a_fifo_is_refused_at_once(tmp_path):
    gltf, _ = _write_gltf(tmp_path)
    buf = tmp_path / _buffer_uri(gltf)
    os.rename(buf, tmp_path / "real.bin")
    os.symlink(tmp_path / "real.bin", buf)
    with pytest.raises(BadInput, match="symlink"):
        load_workpiece(gltf, units="mm", sample_points=500)
    buf.unlink()
    os.mkfifo(buf)
    with pytest.raises(BadInput):
        load_workpiece(gltf, units="mm", sample_points=500)
