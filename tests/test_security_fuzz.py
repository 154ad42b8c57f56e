"""Fuzz every stage-file and job-file field with random types, depths and sizes (issue #49): each load
either succeeds or raises BadInput with one line; never another exception (an internal error)."""
from __future__ import annotations

import datetime
import io
import json
import random

import numpy as np
import pytest
import tomli_w

from camtool.errors import BadInput

from conftest import SAMPLES

SEEDS = range(3)


def _leaf(rng: random.Random):
    return rng.choice([
        lambda: rng.randint(-5, 5), lambda: 10 ** rng.choice([20, 300, 400]), lambda: -(10 ** 350),
        lambda: rng.choice([0.0, -0.0, 1e308, -1e308, 5e-324, float("nan"), float("inf"), float("-inf")]),
        lambda: "", lambda: "x" * rng.choice([1, 300, 5000]), lambda: "a\0b", lambda: "../../etc/passwd",
        lambda: "=1+1", lambda: "\u202e\n\r\t", lambda: True, lambda: False,
        lambda: datetime.datetime(2020, 1, 1), lambda: datetime.date(2020, 1, 1),
    ])()


def random_value(rng: random.Random, depth: int = 0):
    if depth < 6 and rng.random() < 0.35:  # wide only at the top: a few hundred leaves at most
        n = rng.choice([0, 1, 3, 200] if depth == 0 else [0, 1, 2])
        if rng.random() < 0.5:
            return [random_value(rng, depth + 1) for _ in range(n)]
        return {f"k{i}": random_value(rng, depth + 1) for i in range(n)}
    if rng.random() < 0.1:  # deep on purpose
        v = _leaf(rng)
        for _ in range(rng.choice([20, 60, 120])):
            v = [v]
        return v
    return _leaf(rng)


def _one_line(exc: BadInput):
    """What the CLI prints for it: one line (control characters escaped, length bounded)."""
    from camtool.cli import one_line

    line = one_line(exc)
    assert "\n" not in line and "\r" not in line and len(line) <= 2100, line


# ---------------------------------------------------------------- job files

def _job_keys():
    from camtool.job import SCHEMA

    return [(s, k) for s, keys in SCHEMA.items() for k in keys]


@pytest.mark.parametrize("seed", SEEDS)
def test_every_job_field_with_random_values_is_ok_or_one_line(tmp_path, seed):
    from camtool.job import load_job

    rng = random.Random(seed)
    base = (SAMPLES / "sphere.toml").read_text()
    import tomllib

    data = tomllib.loads(base)
    data["workpiece"]["file"] = str(SAMPLES / data["workpiece"]["file"])
    for section, key in _job_keys():
        for _ in range(2):
            job = {s: dict(v) for s, v in data.items()}
            job.setdefault(section, {})[key] = random_value(rng)
            try:
                text = tomli_w.dumps(job)
            except (TypeError, ValueError, RecursionError):
                continue
            f = tmp_path / "job.toml"
            f.write_text(text)
            try:
                load_job(f)
            except BadInput as exc:
                _one_line(exc)


@pytest.mark.parametrize("seed", SEEDS)
def test_set_overrides_with_random_values_are_ok_or_one_line(seed):
    from camtool.job import load_job

    rng = random.Random(100 + seed)
    for section, key in rng.sample(_job_keys(), 40):
        value = random_value(rng)
        try:
            raw = tomli_w.dumps({"v": value}).split("=", 1)[1].strip()
        except (TypeError, ValueError, RecursionError, IndexError):
            raw = str(value)
        try:
            load_job(SAMPLES / "sphere.toml", [f"{section}.{key}={raw}"])
        except BadInput as exc:
            _one_line(exc)


# ---------------------------------------------------------------- stage files

def _boxes():
    from camtool.trajectory import JointPath

    n = 4
    z = np.zeros(n)
    b = np.zeros(n, bool)
    from camtool.path.toolpath import Path
    from camtool.trajectory import Trajectory

    jp = JointPath(q=np.zeros((n, 6)), path_index=np.arange(n), zone=np.zeros(n, int), position_error_mm=z,
                   orientation_error_rad=z, jump=b, reverse_planned=b, retract=b, singular=b, reached=~b)
    path = Path(poses_mm=np.tile(np.eye(4), (n, 1, 1)), segment=np.zeros(n, int), point=np.arange(n),
                zone=np.zeros(n, int), step_over_mm=10.0, pitch_mm=5.0)
    traj = Trajectory(robot_name="seed8", joint_names=tuple(f"j{i}" for i in range(6)), prismatic=np.zeros(6, bool),
                      t_s=np.arange(n, dtype=float), q=np.zeros((n, 6)), qd=np.zeros((n, 6)), qdd=np.zeros((n, 6)),
                      zone=np.zeros(n, int), path_index=np.arange(n), limits={"velocity": np.ones(6)})
    return [jp, path, traj]


def _saved(box, tmp_path):
    from camtool.run.stage_files import save_stage

    f = save_stage(box, tmp_path / "box.npz")
    with np.load(f) as d:
        arrays = {k: d[k] for k in d.files}
    return json.loads(str(arrays.pop("header"))), arrays


def _random_array(rng: random.Random):
    shape = tuple(rng.choice([0, 1, 4, 7]) for _ in range(rng.choice([0, 1, 2, 3])))
    dtype = rng.choice(["f8", "i8", "u1", "?", "c16", "U3", "S2", "f2", "M8[s]", "V4"])
    try:
        return np.zeros(shape, dtype=dtype)
    except (TypeError, ValueError):
        return np.zeros(shape)


@pytest.mark.parametrize("seed", SEEDS)
def test_every_stage_field_with_random_values_is_ok_or_one_line(tmp_path, seed):
    from camtool.run.stage_files import load_stage

    rng = random.Random(200 + seed)
    for box in _boxes():
        header, arrays = _saved(box, tmp_path)
        names = [*arrays, *header["fields"], "format", "version", "kind", "zones", "fields"]
        for name in names:
            for _ in range(3):
                h = json.loads(json.dumps(header))
                a = dict(arrays)
                where = rng.random()
                if name in arrays and where < 0.5:
                    a[name] = _random_array(rng)
                elif name in ("format", "version", "kind", "zones", "fields"):
                    h[name] = random_value(rng)
                else:
                    a.pop(name, None)
                    h["fields"][name] = random_value(rng)
                try:
                    text = json.dumps(h, allow_nan=True)
                except (TypeError, ValueError, RecursionError):
                    continue
                buf = io.BytesIO()
                np.savez(buf, header=np.array(text), **a)
                f = tmp_path / "fuzz.npz"
                f.write_bytes(buf.getvalue())
                try:
                    load_stage(f)
                except BadInput as exc:
                    _one_line(exc)
