"""Stage boxes saved and loaded: exact round trips, versioned header, clear errors."""
import json

import numpy as np
import pytest

from camtool.errors import BadInput
from camtool.run.stage_files import load_stage, save_stage
from camtool.path.toolpath import ZONE_CODE, Path
from camtool.trajectory import JointPath


def small_path():
    poses = np.tile(np.eye(4), (4, 1, 1))
    poses[:, 0, 3] = [0.0, 1.0 / 3.0, 2.0, 3.0]
    return Path(poses, np.zeros(4, np.int32), np.arange(4, dtype=np.int32), np.full(4, ZONE_CODE["work"], np.int32),
                True, 10.0, 5.0)


def small_joint_path():
    n = 3
    q = np.random.default_rng(0).normal(size=(n, 8))
    f = np.zeros(n, bool)
    return JointPath(q, np.array([0, -1, 2]), np.zeros(n, np.int32), np.full(n, 1e-5), np.full(n, 1e-7), f, f, f, f,
                     ~f, {"reverse_plans": [{"index": 2, "xyz_mm": [0.1, 0.2, 0.3]}], "plan_seconds": 0.25,
                          "start_margin": None})


def test_path_round_trip_is_exact(tmp_path):
    p = small_path()
    back = load_stage(save_stage(p, tmp_path / "p.npz"))
    assert isinstance(back, Path)
    assert back.poses_mm.tobytes() == p.poses_mm.tobytes() and back.free_spin is True and back.pitch_mm == 5.0


def test_joint_path_round_trip_keeps_events(tmp_path):
    jp = small_joint_path()
    back = load_stage(save_stage(jp, tmp_path / "jp.npz"), expect=("JointPath",))
    assert back.q.tobytes() == jp.q.tobytes()
    assert back.events == jp.events


def test_boxes_are_read_only():
    jp = small_joint_path()
    with pytest.raises(ValueError):
        jp.q[0, 0] = 1.0
    with pytest.raises(ValueError):
        small_path().zone[0] = 3


def test_header_names_format_version_and_kind(tmp_path):
    f = save_stage(small_path(), tmp_path / "p.npz")
    with np.load(f) as d:
        header = json.loads(str(d["header"]))
    assert header["format"] == "camtool-stage" and header["version"] == 1 and header["kind"] == "Path"


def test_wrong_kind_wrong_version_and_junk_are_bad_input(tmp_path):
    f = save_stage(small_path(), tmp_path / "p.npz")
    with pytest.raises(BadInput, match="holds a Path .*expected JointPath"):
        load_stage(f, expect=("JointPath",))
    with np.load(f) as d:
        arrays = {k: d[k] for k in d.files}
    header = json.loads(str(arrays.pop("header")))
    header["version"] = 99
    bad = tmp_path / "v99.npz"
    np.savez(bad, header=np.array(json.dumps(header)), **arrays)
    with pytest.raises(BadInput, match="version 99"):
        load_stage(bad)
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(BadInput, match="not a camtool stage file"):
        load_stage(junk)
    with pytest.raises(BadInput, match="not found"):
        load_stage(tmp_path / "missing.npz")
