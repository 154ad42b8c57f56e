"""The bad-input corpus: every way a user can hand camtool a broken input, one case each.

Workpieces, job files, robots, controller profiles, programs for `camtool check`
and the command line itself. The contract every case holds camtool to:

- exit code 2 (bad input), or 3 where the input is valid but the plan is
  refused (the case says ``code=3``);
- exactly one line on stderr, starting with ``camtool: error: `` and naming
  what is wrong (``expect``);
- no Python traceback on stdout or stderr;
- no program file (``*.mod``, ``*.pgf``, ``*.JBI``, ``*.csv``) written anywhere
  under the test's folder, the ``-o`` output folder included.

`camtool check` reports the *findings* of a readable but broken program in its
own documented form (docs/controllers.md, "The checker"): exit 2 and one line
per finding on stdout (``file[:line]: message``), nothing on stderr. Cases with
``finding=True`` are held to that form; a check that cannot start at all
(unknown robot, missing file) is a plain ``camtool: error:`` line.

Static inputs live in ``tests/bad_input/`` and ``tests/bad_input/corpus/``; job
files, programs and binary damage are made in ``tmp_path`` by each case.
Most cases run in-process (``cli``); those marked ``sub=True`` run as a real
process, as a user would, including the ones that could crash the interpreter
(URDF through Pinocchio) and the ones whose output the click runner could hide.

A case that fails because camtool misbehaves is kept and marked
``xfail(strict=True, reason="BUG: ...")``.
"""
from __future__ import annotations

import json
import re
import struct
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
import pytest

from conftest import SAMPLES, run_camtool

BAD = Path(__file__).resolve().parent / "bad_input"
CORPUS = BAD / "corpus"
PLATE = SAMPLES / "plate_hole.stl"
LINE_ARC = SAMPLES / "irb2400_line_arc.toml"
PROGRAM_SUFFIXES = {".mod", ".pgf", ".jbi", ".csv"}

# the plate sample's placement (samples/plate_hole.toml): reachable by seed8
PLATE_CELL = "[cell]\nworkpiece_xyz_mm = [700.0, 0.0, 350.0]\nworkpiece_rpy_deg = [0.0, -90.0, 0.0]\n"


def _toml_path(p: Path) -> str:
    return "'" + str(p) + "'"  # a TOML literal string: no escapes


class Workspace:
    """The case's folder: job files, damaged inputs and the -o folder, all under tmp_path."""

    def __init__(self, root: Path, cli):
        self.root = root
        self.out = root / "out"
        self._cli = cli

    def write(self, name: str, data: str | bytes) -> Path:
        p = self.root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, bytes):
            p.write_bytes(data)
        else:
            p.write_text(data)
        return p

    def job(self, body: str = "", workpiece: Path | str | None = PLATE, name: str = "job.toml") -> Path:
        """A job file: ``body`` plus a [workpiece] section (unless the body has one) and the plate's cell."""
        head = ""
        if workpiece is not None and "[workpiece]" not in body:
            head += f"[workpiece]\nfile = {_toml_path(Path(workpiece))}\n\n"
        if "[cell]" not in body:
            head += PLATE_CELL + "\n"
        return self.write(name, head + body)

    def run(self, job: Path, *extra) -> list:
        """`camtool run -q JOB -o OUT ...` (-q: no per-stage progress lines on stderr)."""
        return ["run", "-q", job, "-o", self.out, *extra]

    def run_wp(self, workpiece: Path, *extra) -> list:
        """`camtool run` of the plate job with another workpiece file."""
        return self.run(self.job(workpiece=workpiece), *extra)

    def robot_job(self, robot_file: Path, *extra) -> list:
        return self.run(self.job(f"[robot]\nname = {_toml_path(robot_file)}\n"), *extra)

    def profile_job(self, profile: Path | str, fmt: str = "rapid") -> list:
        p = _toml_path(Path(profile))
        return self.run(self.job(f'[post]\nformats = ["{fmt}"]\nprofiles = {{ {fmt} = {p} }}\n'))

    def path_npz(self) -> Path:
        """A real Path stage file of the plate job (`camtool raster JOB -o DIR`)."""
        d = self.root / "stages"
        r = self._cli("raster", self.job(name="stage_job.toml"), "-o", d)
        assert r.exit_code == 0, r.output
        return d / "path.npz"

    def surface_json(self, change: Callable[[dict], None]) -> Path:
        """The plate's real surface.json (`camtool fit JOB -o DIR`) with ``change`` applied to its JSON."""
        d = self.root / "fitted"
        r = self._cli("fit", self.job(name="fit_job.toml"), "-o", d)
        assert r.exit_code == 0, r.output
        f = d / "surface.json"
        data = json.loads(f.read_text())
        change(data)
        f.write_text(json.dumps(data))  # NaN and inf become NaN / Infinity, as Python's json reads them
        return f

    def damaged_path_npz(self, change: Callable[[dict], None]) -> Path:
        """The plate's real path.npz with ``change`` applied to its arrays (header kept)."""
        f = self.path_npz()
        with np.load(f, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        change(arrays)
        with open(f, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        return f

    def sia20_pulses_profile(self) -> Path:
        """The shipped sia20 INFORM profile plus test pulse factors (positions written as pulses)."""
        from test_post_inform import sia20_profile_with_pulses

        d = self.root / "profiles"
        d.mkdir(exist_ok=True)
        return sia20_profile_with_pulses(d)

    def program(self, fmt: str, robot_name: str, profile_path: Path | None = None) -> Path:
        """A clean program of a smooth trajectory, as the post-processor writes it (CAMTOOL.*)."""
        from post_fixtures import smooth_trajectory

        from camtool.program.profiles import Profile
        from camtool.program.profiles import default_options, load_profile
        from camtool.robots import get_robot
        from postprocessors.abb_rapid import RapidPost
        from postprocessors.csv_joint import CsvPost
        from postprocessors.yaskawa_inform import InformPost

        r = get_robot(robot_name)
        profile = (Profile("<t>", "csv", options=default_options("csv")) if fmt == "csv"
                   else load_profile(profile_path, robot_name, fmt, r))
        post = {"rapid": RapidPost(), "inform": InformPost(), "csv": CsvPost()}[fmt]
        d = self.root / ("programs" if profile_path is None else "programs_" + profile_path.stem)
        d.mkdir(exist_ok=True)
        files = post.write(smooth_trajectory(r, 8), r, profile, d)
        return next(f for f in files if f.suffix.lower() in (".mod", ".jbi", ".csv"))

    def damaged(self, fmt: str, robot_name: str, change: Callable[[str], str],
                profile_path: Path | None = None) -> Path:
        """A clean program with ``change`` applied to its text (same name, so the module name still fits)."""
        p = self.program(fmt, robot_name, profile_path)
        text = p.read_bytes().decode("ascii")
        p.write_bytes(change(text).encode("ascii"))
        return p


# --- program damage -------------------------------------------------------------------------------------

def _rapid_nan(text: str) -> str:
    """The second move's first joint value becomes nan."""
    lines = text.splitlines(keepends=True)
    moves = [i for i, ln in enumerate(lines) if "MoveAbsJ [[" in ln]
    i = moves[1]
    head, rest = lines[i].split("[[", 1)
    lines[i] = head + "[[nan," + rest.split(",", 1)[1]
    return "".join(lines)


def _rapid_1e999(text: str) -> str:
    """The third move's first joint value becomes 1E999, a number too large for a float."""
    lines = text.splitlines(keepends=True)
    i = [i for i, ln in enumerate(lines) if "MoveAbsJ [[" in ln][2]
    head, rest = lines[i].split("[[", 1)
    lines[i] = head + "[[1E999," + rest.split(",", 1)[1]
    return "".join(lines)


def _rapid_cut(text: str) -> str:
    """Cut after the third move: no later move, no ENDPROC, no ENDMODULE."""
    lines = text.splitlines(keepends=True)
    i = [i for i, ln in enumerate(lines) if "MoveAbsJ [[" in ln][2]
    return "".join(lines[:i + 1])


def _jbi_cut(text: str) -> str:
    """Cut in the middle of the MOVJ lines (no END)."""
    lines = text.splitlines(keepends=True)
    i = [i for i, ln in enumerate(lines) if ln.startswith("MOVJ")][3]
    return "".join(lines[:i])


def _jbi_pulse_beyond_int64(text: str) -> str:
    lines = text.split("\r\n")
    # the first position stated in pulses (MOVL positions are ///RECTAN poses)
    i = next(i for i, ln in enumerate(lines) if re.fullmatch(r"C\d{5}=-?\d+(,-?\d+)*", ln))
    name, rest = lines[i].split("=", 1)
    values = rest.split(",")
    values[0] = "99999999999999999999"  # > 2**63
    lines[i] = name + "=" + ",".join(values)
    return "\r\n".join(lines)


def _csv_cut_mid_row(text: str) -> str:
    lines = text.splitlines(keepends=True)
    return "".join(lines[:4]) + lines[4][: len(lines[4]) // 2]


def _csv_cut_at_row(text: str) -> str:
    """Whole rows only: the trailer and the last two rows are gone."""
    lines = text.splitlines(keepends=True)
    return "".join(lines[:-3])


def _csv_trailer_count(text: str) -> str:
    lines = text.splitlines(keepends=True)
    assert lines[-1].startswith("# END ")
    return "".join(lines[:-1]) + "# END 99 rows\n"


def _csv_nan_time(text: str) -> str:
    lines = text.splitlines(keepends=True)
    lines[3] = "nan," + lines[3].split(",", 1)[1]
    return "".join(lines)


def _rapid_zero_duration(text: str) -> str:
    return re.sub(r"\\T:=[0-9.]+", r"\\T:=0.0000", text)


def _jbi_vj_nan(text: str) -> str:
    lines = text.split("\r\n")
    i = [i for i, ln in enumerate(lines) if ln.startswith("MOVJ")][2]
    lines[i] = re.sub(r"VJ=[0-9.]+", "VJ=nan", lines[i])
    return "\r\n".join(lines)


def _path_nan_pose(a: dict) -> None:
    q = a["poses_mm"].copy()
    q[5, 0, 3] = np.nan
    a["poses_mm"] = q


def _path_3x4_poses(a: dict) -> None:
    a["poses_mm"] = a["poses_mm"][:, :3, :]


def _path_short_segment(a: dict) -> None:
    a["segment"] = a["segment"][:10]


def _truncated_npz(w: Workspace) -> Path:
    f = w.path_npz()
    f.write_bytes(f.read_bytes()[:5000])
    return f


# --- generated workpieces ------------------------------------------------------------------------------

def _stl_truncated(w: Workspace) -> Path:
    tri = struct.pack("<12fH", *([0.0] * 12), 0)
    return w.write("truncated.stl", b"\0" * 80 + struct.pack("<I", 1000) + tri * 3 + tri[:20])


def _ply_binary_truncated(w: Workspace) -> Path:
    head = (b"ply\nformat binary_little_endian 1.0\nelement vertex 10\n"
            b"property float x\nproperty float y\nproperty float z\nend_header\n")
    return w.write("truncated_binary.ply", head + struct.pack("<6f", 0, 0, 0, 100, 0, 0) + b"\x01\x02")


def _folder(w: Workspace, name: str) -> Path:
    p = w.root / name
    p.mkdir()
    return p


def _under_file(w: Workspace) -> Path:
    """An output folder below a regular file: it can never be created."""
    w.write("plain.txt", "a regular file\n")
    return w.root / "plain.txt" / "out"


# --- the corpus ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Case:
    id: str
    argv: Callable[[Workspace], list]
    expect: tuple[str, ...] = ()     # each must be in the error line (or, for findings, in stdout)
    code: int = 2
    sub: bool = False                # run as a separate process
    finding: bool = False            # `camtool check` findings: stdout lines, not `camtool: error:`
    bug: str = ""                    # xfail(strict=True) reason, "BUG: ..."
    timeout: float | None = None     # seconds, for a case that could hang (a separate process, then)


def C(id, argv, *expect, code=2, sub=False, finding=False, bug="", timeout=None):
    return Case(id, argv, tuple(expect), code, sub or timeout is not None, finding, bug, timeout)


NEWLINE_BUG = ("BUG: a name holding a newline is echoed raw, so the error is two lines on stderr "
               "(camtool/cli.py prints str(exc) as is)")
CLICK_BUG = "BUG: click's usage error is 4 lines on stderr (Usage/Try/blank/Error), not one `camtool: error:` line"


WORKPIECES = [
    C("wp-empty-stl", lambda w: w.run_wp(w.write("empty.stl", b"")), "empty.stl", "empty"),
    C("wp-empty-xyz", lambda w: w.run_wp(CORPUS / "empty.xyz"), "empty.xyz", "empty"),
    C("wp-stl-binary-truncated", lambda w: w.run_wp(_stl_truncated(w)), "truncated.stl", "truncated"),
    C("wp-stl-ascii-no-endsolid", lambda w: w.run_wp(CORPUS / "ascii_no_endsolid.stl"),
      "ascii_no_endsolid.stl", "endsolid"),
    C("wp-stl-nan-triangle", lambda w: w.run_wp(BAD / "nan_triangle.stl"), "nan_triangle.stl", sub=True),
    C("wp-stl-holding-xyz-text", lambda w: w.run_wp(CORPUS / "points_named.stl"), "points_named.stl"),
    C("wp-ply-cut-short", lambda w: w.run_wp(BAD / "cut_short.ply"), "cut_short.ply", "truncated"),
    C("wp-ply-minus-inf", lambda w: w.run_wp(BAD / "minus_inf.ply"), "minus_inf.ply"),
    C("wp-ply-bad-header", lambda w: w.run_wp(CORPUS / "bad_header.ply"), "bad_header.ply"),
    C("wp-ply-binary-truncated", lambda w: w.run_wp(_ply_binary_truncated(w)), "truncated_binary.ply",
      "truncated"),
    C("wp-ply-holding-png", lambda w: w.run_wp(CORPUS / "png_named.ply"), "png_named.ply"),
    C("wp-obj-vertex-two-coords", lambda w: w.run_wp(CORPUS / "vertex_two_coords.obj"), "vertex_two_coords.obj"),
    C("wp-obj-face-index-99", lambda w: w.run_wp(CORPUS / "face_index_99.obj"), "face_index_99.obj"),
    C("wp-obj-vertex-word", lambda w: w.run_wp(CORPUS / "vertex_word.obj"), "vertex_word.obj"),
    C("wp-pcd-cut-short", lambda w: w.run_wp(BAD / "cut_short.pcd"), "cut_short.pcd"),
    C("wp-pcd-no-data-line", lambda w: w.run_wp(CORPUS / "no_data_line.pcd"), "no_data_line.pcd", "header"),
    C("wp-off-counts-wrong", lambda w: w.run_wp(CORPUS / "off_counts_wrong.off"), "off_counts_wrong.off"),
    C("wp-glb-garbage", lambda w: w.run_wp(CORPUS / "garbage.glb"), "garbage.glb"),
    C("wp-xyz-nan-inf", lambda w: w.run_wp(BAD / "nan.xyz"), "nan.xyz", "NaN or infinite"),
    C("wp-xyz-two-columns", lambda w: w.run_wp(CORPUS / "two_columns.xyz"), "two_columns.xyz"),
    C("wp-xyz-words", lambda w: w.run_wp(CORPUS / "words.xyz"), "words.xyz"),
    C("wp-xyz-two-points", lambda w: w.run_wp(BAD / "two_points.xyz"), "two_points.xyz", "at least 3"),
    C("wp-xyz-collinear", lambda w: w.run_wp(BAD / "collinear.xyz"), "collinear.xyz", "line"),
    C("wp-xyz-huge-1e12", lambda w: w.run_wp(BAD / "huge.xyz"), "huge.xyz", sub=True),
    C("wp-xyz-huge-1e300", lambda w: w.run_wp(CORPUS / "huge_1e300.xyz"), "huge_1e300.xyz"),
    C("wp-wrong-extension-docx", lambda w: w.run_wp(BAD / "notes.docx"), "notes.docx", "unsupported file type"),
    C("wp-folder", lambda w: w.run_wp(_folder(w, "part.stl")), "part.stl", "folder"),
    C("wp-missing", lambda w: w.run_wp(w.root / "missing.ply"), "missing.ply", "not found"),
    C("wp-fit-input-truncated-stl", lambda w: ["fit", _stl_truncated(w), "-o", w.out], "truncated.stl"),
    C("wp-fit-input-folder", lambda w: ["fit", _folder(w, "scan.xyz"), "-o", w.out], "scan.xyz", "folder"),
    C("wp-obj-face-index-0", lambda w: ["fit", CORPUS / "face_index_0.obj", "-o", w.out], "face_index_0.obj",
      bug="BUG: an OBJ face with index 0 (OBJ counts from 1) is read as another triangle and the fit succeeds "
          "(exit 0)"),
    C("wp-file-name-with-newline", lambda w: w.run(w.job('[workpiece]\nfile = "miss\\ning.stl"\n')),
      "not found", bug=NEWLINE_BUG),
]

JOBS = [
    C("job-toml-unclosed-table", lambda w: w.run(w.write("job.toml", "[raster\npitch_mm = 5\n")),
      "job.toml", "TOML syntax error"),
    C("job-toml-duplicate-key", lambda w: w.run(w.job("[raster]\npitch_mm = 5\npitch_mm = 6\n")),
      "job.toml", "TOML syntax error", sub=True),
    C("job-toml-not-utf8", lambda w: w.run(w.write("job.toml", b"[raster]\npitch_mm = \xff\xfe\n")), "job.toml"),
    C("job-unknown-section-typo", lambda w: w.run(w.job("[rastr]\npitch_mm = 5\n")), "rastr", "'raster'"),
    C("job-unknown-key-typo", lambda w: w.run(w.job("[raster]\nstep_ovr_mm = 5\n")),
      "raster.step_ovr_mm", "did you mean 'step_over_mm'"),
    C("job-unknown-key-typo-planner", lambda w: w.run(w.job("[planner]\nmax_iteration = 50\n")),
      "planner.max_iteration", "did you mean 'max_iterations'"),
    C("job-unknown-key-typo-tool", lambda w: w.run(w.job("[tool]\ntcp_xyz = [0, 0, 100]\n")),
      "tool.tcp_xyz", "did you mean 'tcp_xyz_mm'"),
    C("job-section-is-a-value",
      lambda w: w.run(w.write("job.toml", f"raster = 5\n[workpiece]\nfile = {_toml_path(PLATE)}\n")),
      "raster", "table"),
    C("job-type-string-for-float", lambda w: w.run(w.job('[raster]\npitch_mm = "5"\n')), "raster.pitch_mm"),
    C("job-type-float-for-int", lambda w: w.run(w.job("[fit]\niterations = 10.5\n")), "fit.iterations"),
    C("job-type-bool-for-float", lambda w: w.run(w.job("[raster]\nstep_over_mm = true\n")), "raster.step_over_mm"),
    C("job-type-vec2-for-vec3", lambda w: w.run(w.job("[cell]\nworkpiece_xyz_mm = [700.0, 0.0]\n")),
      "cell.workpiece_xyz_mm"),
    C("job-fit-iterations-2e9", lambda w: w.run(w.job("[fit]\niterations = 2_000_000_000\n")),
      "fit.iterations", sub=True),
    C("job-fit-iterations-2e9-float", lambda w: w.run(w.job("[fit]\niterations = 2e9\n")), "fit.iterations"),
    C("job-reverse-samples-2e9", lambda w: w.run(w.job("[planner]\nreverse_samples = 2_000_000_000\n")),
      "planner.reverse_samples"),
    C("job-max-iterations-2e9", lambda w: w.run(w.job("[planner]\nmax_iterations = 2_000_000_000\n")),
      "planner.max_iterations"),
    C("job-arc-points-1e8", lambda w: w.run(w.job('[task]\nkind = "cartesian"\narc_points = 100_000_000\n')),
      "task.arc_points"),
    C("job-angle-deg-minus-1e308", lambda w: w.run(w.job("[raster]\nangle_deg = -1e308\n")), "raster.angle_deg"),
    C("job-pitch-minus-1", lambda w: w.run(w.job("[raster]\npitch_mm = -1\n")), "raster.pitch_mm", "0.1..10000"),
    C("job-formats-empty", lambda w: w.run(w.job("[post]\nformats = []\n")), "post.formats"),
    C("job-formats-twice", lambda w: w.run(w.job('[post]\nformats = ["rapid", "rapid"]\n')), "rapid"),
    C("job-formats-unknown-plugin", lambda w: w.run(w.job('[post]\nformats = ["gcode"]\n')), "gcode"),
    C("job-program-name-empty", lambda w: w.run(w.job('[post]\nprogram_name = ""\n')), "post.program_name"),
    C("job-tool-offset-1e12", lambda w: w.run(w.job("[tool]\ntcp_xyz_mm = [0.0, 0.0, 1e12]\n")),
      "tool.tcp_xyz_mm"),
    C("job-units-cm", lambda w: w.run(w.job(f'[workpiece]\nfile = {_toml_path(PLATE)}\nunits = "cm"\n')),
      "workpiece.units"),
    C("job-missing-workpiece-file", lambda w: w.run(w.job("[raster]\npitch_mm = 5\n", workpiece=None)),
      "workpiece.file", sub=True),
    C("job-empty-workpiece-file", lambda w: w.run(w.job('[workpiece]\nfile = ""\n')), "workpiece.file"),
    C("job-robot-file-missing", lambda w: w.run(w.job('[robot]\nname = "no_such_arm.toml"\n')),
      "robot.name", "no_such_arm.toml", "not found"),
    C("job-robot-unknown-builtin", lambda w: w.run(w.job('[robot]\nname = "ur5"\n')), "robot.name", "ur5"),
    C("job-robot-param-unknown", lambda w: w.run(w.job("[robot]\nparams = { L9 = 300.0 }\n")), "L9"),
    C("job-robot-param-negative", lambda w: w.run(w.job("[robot]\nparams = { L1 = -300.0 }\n")), "L1"),
    C("job-home-deg-wrong-count", lambda w: w.run(w.job("[robot]\nhome_deg = [0.0, 10.0]\n")), "home_deg"),
    C("job-is-a-folder", lambda w: w.run(_folder(w, "job.toml")), "job.toml", "directory"),
    C("job-missing", lambda w: w.run(w.root / "nojob.toml"), "nojob.toml", "not found"),
    C("set-nan", lambda w: w.run(w.job(), "--set", "raster.pitch_mm=nan"), "raster.pitch_mm"),
    C("set-nan-in-vector", lambda w: w.run(w.job(), "--set", "cell.workpiece_xyz_mm=[nan, 0, 0]"),
      "cell.workpiece_xyz_mm"),
    C("set-inf-tool-offset", lambda w: w.run(w.job(), "--set", "tool.tcp_xyz_mm=[0, 0, inf]"), "tool.tcp_xyz_mm"),
    C("set-unknown-key-typo", lambda w: w.run(w.job(), "--set", "raster.pich_mm=5"),
      "raster.pich_mm", "did you mean 'pitch_mm'"),
    C("set-unknown-section-typo", lambda w: w.run(w.job(), "--set", "plannr.seed=3"),
      "plannr", "did you mean 'planner'"),
    C("set-no-equals", lambda w: w.run(w.job(), "--set", "raster.pitch_mm"), "--set"),
    C("set-iterations-2e9", lambda w: w.run(w.job(), "--set", "fit.iterations=2e9"), "fit.iterations"),
    C("job-key-with-newline", lambda w: w.run(w.job('[raster]\n"step\\nover_mm" = 5\n')), "unknown key",
      bug=NEWLINE_BUG),
    C("set-key-with-newline", lambda w: w.run(w.job(), "--set", "raster.pitch\n_mm=5"), "unknown key",
      bug=NEWLINE_BUG),
    C("job-fit-seed-negative", lambda w: ["fit", w.job("[fit]\nseed = -1\n"), "-o", w.out], "fit.seed",
      bug="BUG: fit.seed = -1 passes validation and numpy refuses it: exit 1, "
          "`internal error: ValueError: expected non-negative integer`"),
    C("job-planner-seed-negative", lambda w: ["plan", w.job("[planner]\nseed = -1\n"), "-o", w.out],
      "planner.seed",
      bug="BUG: planner.seed = -1 passes validation and numpy refuses it: exit 1, "
          "`internal error: ValueError: expected non-negative integer`"),
    C("job-step-over-1e-9", lambda w: ["raster", w.job("[raster]\nstep_over_mm = 1e-9\n"), "-o", w.out],
      "step_over_mm", sub=True,
      bug="BUG: raster.step_over_mm = 1e-9 is not bounded (pitch_mm = 1e-9 is: 'would give about ... poses'): "
          "exit 1, `internal error: MemoryError: Unable to allocate 2.88 TiB`"),
    C("job-home-deg-1e300",
      lambda w: w.run(LINE_ARC, "--set", "robot.home_deg=[1e300, 0, 0, 0, 0, 0]"), "robot.home_deg", sub=True,
      bug="BUG: robot.home_deg is not held to the documented +-3600 deg (only float/vec3 keys are): the "
          "cartesian job runs, exit 0, writes LINEARC.mod, numpy overflow RuntimeWarning on stderr"),
    C("job-cartesian-zero-lines",
      lambda w: w.run(LINE_ARC, "--set", "task.line_down_mm=0", "--set", "task.line_side_mm=0"),
      "line", sub=True,
      bug="BUG: zero-length cartesian lines are not refused: a numpy RuntimeWarning (2 lines) on stderr, then "
          "exit 3 with program-check speed findings (j1 1113 deg/s over a 0.0001 s step)"),
    C("job-cartesian-path-tol-1e-300",
      lambda w: w.run(LINE_ARC, "--set", "task.path_tol_mm=1e-300"), "task.path_tol_mm", timeout=10,
      bug="BUG: task.path_tol_mm = 1e-300 has no lower bound: the run refines for more than 90 s "
          "(numpy overflow RuntimeWarnings on stderr) instead of refusing the value"),
]

ROBOTS = [
    C("robot-joint-list-of-numbers", lambda w: w.robot_job(CORPUS / "joint_not_tables.toml"),
      "joint_not_tables.toml", "joint", sub=True),
    C("robot-flange-two-values", lambda w: w.robot_job(CORPUS / "flange_two_values.toml"),
      "flange_two_values.toml", "xyz_mm"),
    C("robot-unknown-param-name", lambda w: w.robot_job(CORPUS / "string_param.toml"),
      "string_param.toml", "a_mm", "L7"),
    C("robot-param-is-string", lambda w: w.robot_job(CORPUS / "param_is_string.toml"),
      "param_is_string.toml", "L1"),
    C("robot-nan-limit", lambda w: w.robot_job(CORPUS / "nan_limit.toml"), "nan_limit.toml", "upper"),
    C("robot-inf-velocity", lambda w: w.robot_job(CORPUS / "inf_velocity.toml"), "inf_velocity.toml", "velocity"),
    C("robot-duplicate-joint-names", lambda w: w.robot_job(CORPUS / "duplicate_joint_names.toml"),
      "duplicate_joint_names.toml", "j1", "unique"),
    C("robot-flange-xyz-typo", lambda w: w.robot_job(CORPUS / "flange_xyz_typo.toml"),
      "flange_xyz_typo.toml", "did you mean xyz_mm"),
    C("robot-joint-a-typo", lambda w: w.robot_job(CORPUS / "joint_a_typo.toml"),
      "joint_a_typo.toml", "did you mean a_mm"),
    C("robot-lower-above-upper", lambda w: w.robot_job(CORPUS / "lower_above_upper.toml"),
      "lower_above_upper.toml", "lower"),
    C("robot-toml-syntax-error", lambda w: w.robot_job(CORPUS / "robot_syntax_error.toml"),
      "robot_syntax_error.toml", "TOML"),
    C("robot-link-1e9-mm", lambda w: w.robot_job(CORPUS / "link_1e9_mm.toml"), "link_1e9_mm.toml", "a_mm"),
    C("robot-no-joints", lambda w: w.robot_job(CORPUS / "no_joints.toml"), "no_joints.toml", "joint"),
    C("robot-fk-file-wrong-count", lambda w: ["fk", CORPUS / "ok_two_link.toml", "0", "0", "0"], "2 joints"),
    C("urdf-no-movable-joint", lambda w: w.robot_job(BAD / "no_joints.urdf"), "no_joints.urdf", sub=True),
    C("urdf-broken-xml", lambda w: w.robot_job(CORPUS / "broken_xml.urdf"), "broken_xml.urdf", "XML", sub=True),
    C("urdf-continuous-joint", lambda w: w.robot_job(CORPUS / "continuous_joint.urdf"),
      "continuous_joint.urdf", "continuous", sub=True),
    C("urdf-nan-origin", lambda w: w.robot_job(CORPUS / "nan_origin.urdf"), "nan_origin.urdf", sub=True),
    C("urdf-zero-axis", lambda w: ["fk", CORPUS / "zero_axis.urdf", "0"], "zero_axis.urdf", sub=True),
    C("urdf-no-limit", lambda w: ["fk", CORPUS / "no_limit.urdf", "0"], "no_limit.urdf", "limit", sub=True),
]

PROFILES = [
    C("profile-missing", lambda w: w.profile_job(w.root / "cell3_irc5.toml"), "cell3_irc5.toml", "not found",
      sub=True),
    C("profile-toml-syntax-error", lambda w: w.profile_job(CORPUS / "profile_syntax_error.toml"),
      "profile_syntax_error.toml", "TOML"),
    C("profile-for-other-format", lambda w: w.profile_job(CORPUS / "profile_for_inform.toml"),
      "profile_for_inform.toml", "format"),
    C("profile-unknown-joint", lambda w: w.profile_job(CORPUS / "profile_unknown_joint.toml"),
      "profile_unknown_joint.toml", "elbow"),
    C("profile-nan-offset", lambda w: w.profile_job(CORPUS / "profile_nan_offset.toml"),
      "profile_nan_offset.toml", "offset"),
    C("profile-unknown-option", lambda w: w.profile_job(CORPUS / "profile_unknown_option.toml"),
      "profile_unknown_option.toml", "zone_name"),
    C("profile-is-a-folder", lambda w: w.profile_job(_folder(w, "prof.toml")), "prof.toml"),
    C("profile-no-default", lambda w: w.run(w.job('[robot]\nname = "irb2400"\n[post]\nformats = ["inform"]\n')),
      "inform", "irb2400", "post.profiles"),
    # the misspelt key names a profile that check would refuse (axes.elbow) if it were read at all
    C("profile-format-typo",
      lambda w: ["check", w.program("rapid", "seed8"), "--job",
                 w.job("[post]\nformats = [\"rapid\"]\n"
                       f"profiles = {{ rapd = {_toml_path(CORPUS / 'profile_unknown_joint.toml')} }}\n")],
      "rapd",
      bug="BUG: a post.profiles key naming no post-processor (rapd for rapid) is ignored without a word: the "
          "shipped default profile is used instead of the user's, exit 0"),
]

CHECK = [
    C("check-rapid-nan-joint", lambda w: ["check", w.damaged("rapid", "seed8", _rapid_nan), "--robot", "seed8"],
      "finite", finding=True, sub=True),
    C("check-rapid-1e999-joint",
      lambda w: ["check", w.damaged("rapid", "seed8", _rapid_1e999), "--robot", "seed8"], "finite", finding=True),
    C("check-rapid-truncated", lambda w: ["check", w.damaged("rapid", "seed8", _rapid_cut), "--robot", "seed8"],
      "ENDMODULE", finding=True),
    C("check-jbi-truncated", lambda w: ["check", w.damaged("inform", "sia20", _jbi_cut), "--robot", "sia20"],
      "END", finding=True),
    C("check-jbi-pulse-beyond-int64",
      # pulse positions need pulse factors: the shipped sia20 profile has none (///RECTAN poses)
      lambda w: ["check", w.damaged("inform", "sia20", _jbi_pulse_beyond_int64, w.sia20_pulses_profile()),
                 "--robot", "sia20", "--profile", w.sia20_pulses_profile()],
      "int64", finding=True, sub=True),
    C("check-csv-cut-mid-row",
      lambda w: ["check", w.damaged("csv", "irb2400", _csv_cut_mid_row), "--robot", "irb2400"], finding=True),
    C("check-csv-cut-at-row-boundary",
      lambda w: ["check", w.damaged("csv", "irb2400", _csv_cut_at_row), "--robot", "irb2400"],
      "END", finding=True),
    C("check-csv-trailer-wrong-count",
      lambda w: ["check", w.damaged("csv", "irb2400", _csv_trailer_count), "--robot", "irb2400"], finding=True),
    C("check-csv-nan-time", lambda w: ["check", w.damaged("csv", "irb2400", _csv_nan_time), "--robot", "irb2400"],
      "t_s", finding=True),
    C("check-csv-wrong-robot", lambda w: ["check", w.program("csv", "irb2400"), "--robot", "sia20"],
      "sia20", finding=True),
    C("check-rapid-wrong-robot", lambda w: ["check", w.program("rapid", "seed8"), "--robot", "irb2400"],
      finding=True),
    C("check-jbi-wrong-robot", lambda w: ["check", w.program("inform", "sia20"), "--robot", "seed8"],
      finding=True),
    C("check-empty-jbi", lambda w: ["check", w.write("EMPTY.JBI", b""), "--robot", "sia20"], finding=True),
    C("check-rapid-zero-duration",
      lambda w: ["check", w.damaged("rapid", "seed8", _rapid_zero_duration), "--robot", "seed8"],
      "not positive", finding=True),
    C("check-jbi-vj-nan", lambda w: ["check", w.damaged("inform", "sia20", _jbi_vj_nan), "--robot", "sia20"],
      "VJ=nan", finding=True),
    C("check-pgf-garbage", lambda w: ["check", w.write("GARBAGE.pgf", "<Program><Module>"), "--robot", "seed8"],
      "GARBAGE.pgf", finding=True),
    C("check-pgf-module-missing",
      lambda w: ["check", w.write("MAIN.pgf", '<?xml version="1.0" encoding="ISO-8859-1" ?>\n<Program>\n'
                                  "  <Module>NOPE.mod</Module>\n</Program>\n"), "--robot", "seed8"],
      "NOPE.mod", finding=True),
    C("check-folder-named-mod", lambda w: ["check", _folder(w, "DIR.mod"), "--robot", "seed8"], "DIR.mod"),
    C("check-unknown-robot", lambda w: ["check", w.program("csv", "irb2400"), "--robot", "nosuchbot"],
      "nosuchbot"),
    C("check-no-robot", lambda w: ["check", w.program("csv", "irb2400")], "--robot"),
    C("check-missing-program", lambda w: ["check", w.root / "GONE.mod", "--robot", "seed8"], "GONE.mod"),
    C("check-unknown-extension", lambda w: ["check", w.write("prog.txt", "MOVJ\n"), "--robot", "seed8"],
      "prog.txt", "--format"),
    C("check-unknown-format", lambda w: ["check", w.program("csv", "irb2400"), "--robot", "irb2400",
                                         "--format", "gcode"], "gcode"),
    C("check-profile-missing", lambda w: ["check", w.program("inform", "sia20"), "--robot", "sia20",
                                          "--profile", w.root / "nope.toml"], "nope.toml"),
    C("check-robot-file-broken", lambda w: ["check", w.program("csv", "irb2400"), "--robot",
                                            CORPUS / "duplicate_joint_names.toml"], "duplicate_joint_names.toml"),
]

STAGE_FILES = [  # --from: a stage file of the wrong kind, damaged, or edited into nonsense
    C("from-path-npz-into-time", lambda w: ["time", w.job(), "--from", w.path_npz(), "-o", w.out],
      "path.npz", "Path", "JointPath", sub=True),
    C("from-path-npz-into-post", lambda w: ["post", w.job(), "--from", w.path_npz(), "-o", w.out],
      "path.npz", "Trajectory"),
    C("from-path-npz-into-raster", lambda w: ["raster", w.job(), "--from", w.path_npz(), "-o", w.out],
      "path.npz"),
    C("from-junk-into-plan", lambda w: ["plan", w.job(), "--from", BAD / "notes.docx", "-o", w.out],
      "notes.docx", "stage file"),
    C("from-missing-into-time", lambda w: ["time", w.job(), "--from", w.root / "gone.npz", "-o", w.out],
      "gone.npz"),
    C("from-truncated-npz", lambda w: ["plan", w.job(), "--from", _truncated_npz(w), "-o", w.out], "path.npz",
      bug="BUG: a truncated .npz stage file is not caught (zipfile.BadZipFile is not among the caught errors): "
          "exit 1, `internal error: BadZipFile: File is not a zip file`"),
    C("from-path-nan-pose", lambda w: ["plan", w.job(), "--from", w.damaged_path_npz(_path_nan_pose), "-o", w.out],
      "path.npz",
      bug="BUG: a Path stage file with a NaN pose is not checked on load: exit 1, "
          "`internal error: LinAlgError: Array must not contain infs or NaNs`"),
    C("from-path-3x4-poses",
      lambda w: ["plan", w.job(), "--from", w.damaged_path_npz(_path_3x4_poses), "-o", w.out], "path.npz",
      bug="BUG: a Path stage file with 3x4 poses is not checked on load: exit 1, "
          "`internal error: ValueError: operands could not be broadcast together`"),
    C("from-path-short-segment-array",
      lambda w: ["plan", w.job(), "--from", w.damaged_path_npz(_path_short_segment), "-o", w.out], "path.npz",
      bug="BUG: a Path stage file whose arrays disagree in length is not checked on load: exit 1, "
          "`internal error: ValueError: operands could not be broadcast together`"),
    C("from-surface-nan-normal",
      lambda w: ["raster", w.job(), "--from", w.surface_json(lambda d: d.update(normal=[float("nan"), 0, 0])),
                 "-o", w.out], "surface.json",
      bug="BUG: a surface.json with a NaN normal is not checked on load: RuntimeWarning lines on stderr, exit 1, "
          "`internal error: LinAlgError: SVD did not converge`"),
    C("from-surface-zero-normal",
      lambda w: ["raster", w.job(), "--from", w.surface_json(lambda d: d.update(normal=[0, 0, 0])),
                 "-o", w.out], "surface.json",
      bug="BUG: a surface.json with a zero normal is not checked on load: exit 1, "
          "`internal error: ValueError: Non-positive determinant ...`"),
    C("from-surface-origin-infinity",
      lambda w: ["raster", w.job(), "--from", w.surface_json(lambda d: d.update(origin_mm=[float("inf"), 0, 0])),
                 "-o", w.out], "surface.json",
      bug="BUG: a surface.json with an infinite origin is not checked on load: RuntimeWarning lines on stderr, "
          "exit 1, `internal error: ValueError: data must be finite, check for nan or inf values`"),
    C("from-surface-boundary-1e300",
      lambda w: ["raster", w.job(), "--from",
                 w.surface_json(lambda d: d["boundary"].update(outer_uv=[[0, 0], [1e300, 0], [0, 1e300]])),
                 "-o", w.out], "surface.json",
      bug="BUG: a surface.json with a 1e300 mm boundary is not checked on load: RuntimeWarning on stderr, "
          "exit 1, `internal error: ValueError: Maximum allowed size exceeded`"),
    C("from-surface-not-json", lambda w: ["raster", w.job(), "--from", BAD / "nan.xyz", "-o", w.out], "nan.xyz",
      "surface"),
    C("from-surface-no-model", lambda w: ["raster", w.job(), "--from", w.surface_json(lambda d: d.pop("model")),
                                          "-o", w.out], "surface.json"),
]

CLI = [
    C("fk-inf", lambda w: ["fk", "seed8", *["0"] * 7, "inf"], "finite", sub=True),
    C("fk-nan", lambda w: ["fk", "seed8", *["0"] * 7, "nan"], "finite"),
    C("fk-1e300", lambda w: ["fk", "seed8", *["0"] * 7, "1e300"], "finite"),
    C("fk-too-few-values", lambda w: ["fk", "seed8", "0", "0", "0"], "8 joints"),
    C("fk-too-many-values", lambda w: ["fk", "irb2400", *["0"] * 7], "6 joints"),
    C("fk-word-value", lambda w: ["fk", "seed8", *["0"] * 7, "zero"], "numbers"),
    C("fk-unknown-robot", lambda w: ["fk", "ur5", "0"], "ur5"),
    C("cli-unknown-option", lambda w: w.run(w.job(), "--bogus"), "--bogus", sub=True, bug=CLICK_BUG),
    C("cli-unknown-command", lambda w: ["frobnicate", w.job()], "frobnicate", bug=CLICK_BUG),
    C("cli-missing-required-outdir", lambda w: ["plan", w.job()], "--outdir", bug=CLICK_BUG),
    C("cli-fit-threshold-negative", lambda w: ["fit", PLATE, "--threshold", "-1", "-o", w.out], "--threshold",
      bug=CLICK_BUG),
    C("outdir-under-regular-file-run", lambda w: ["run", "-q", w.job(), "-o", _under_file(w)], "plain.txt",
      sub=True),
    C("outdir-under-regular-file-raster", lambda w: ["raster", w.job(), "-o", _under_file(w)], "plain.txt"),
    C("outdir-under-regular-file-fit", lambda w: ["fit", w.job(), "-o", _under_file(w)], "plain.txt"),
    C("outdir-is-regular-file", lambda w: ["run", "-q", w.job(), "-o", w.write("plain.txt", "x\n")], "plain.txt"),
    C("plan-refused-cartesian-out-of-reach",
      lambda w: ["run", "-q", LINE_ARC, "--set", "task.cart_start_mm=[5000, 0, 1000]", "-o", w.out],
      "no closed-form IK", code=3, sub=True),
]

CASES = WORKPIECES + JOBS + ROBOTS + PROFILES + CHECK + STAGE_FILES + CLI


def _params():
    out = []
    for c in CASES:
        marks = []  # every bug the corpus found is fixed; c.bug keeps what each case once caught
        out.append(pytest.param(c, id=c.id, marks=marks))
    return out


FINDING = re.compile(r"^[^\s:][^:]*\.\w+(:\d+)?: \S")


def _programs(root: Path) -> set[Path]:
    return {p for p in root.rglob("*") if p.is_file() and p.suffix.lower() in PROGRAM_SUFFIXES}


def test_corpus_is_large_and_ids_unique():
    ids = [c.id for c in CASES]
    assert len(ids) == len(set(ids)) and len(ids) >= 60


def test_every_corpus_file_is_used():
    source = Path(__file__).read_text()
    unused = [f.name for f in CORPUS.iterdir() if f'"{f.name}"' not in source]
    assert not unused


@pytest.mark.parametrize("robot,q", [("ok_two_link.toml", ["0", "0"]), ("ok_one_joint.urdf", ["0"])])
def test_broken_robots_differ_from_a_valid_base(cli, robot, q):
    """The robot files here are each a valid base with one defect: the bases themselves load."""
    r = cli("fk", CORPUS / robot, *q, "--json")
    assert r.exit_code == 0 and r.stderr == "", r.output


@pytest.mark.parametrize("case", _params())
def test_bad_input(case: Case, tmp_path, cli, monkeypatch):
    monkeypatch.chdir(tmp_path)  # anything written to a relative default lands where it is looked for
    w = Workspace(tmp_path, cli)
    argv = [str(a) for a in case.argv(w)]
    before = _programs(tmp_path)
    if case.timeout is not None:
        try:
            r = subprocess.run([sys.executable, "-m", "camtool.cli", *argv], capture_output=True, text=True,
                               cwd=tmp_path, timeout=case.timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"camtool {' '.join(argv)}: no answer within {case.timeout} s")
        code, out, err = r.returncode, r.stdout, r.stderr
    elif case.sub:
        r = run_camtool(*argv, cwd=tmp_path)
        code, out, err = r.returncode, r.stdout, r.stderr
    else:
        r = cli(*argv)
        code, out, err = r.exit_code, r.stdout, r.stderr
    shown = f"camtool {' '.join(argv)}\nexit {code}\n--- stdout\n{out}\n--- stderr\n{err}"

    assert "Traceback" not in out and "Traceback" not in err, shown
    assert code == case.code, shown
    if case.finding:  # `camtool check`: one line per finding on stdout, `file[:line]: message`
        lines = out.splitlines()
        assert err == "", shown
        assert lines and all(FINDING.match(ln) for ln in lines), shown
        assert all(e in out for e in case.expect), shown
    else:
        lines = err.splitlines()
        assert len(lines) == 1, shown
        assert lines[0].startswith("camtool: error: "), shown
        assert all(e in lines[0] for e in case.expect), shown
    written = _programs(tmp_path) - before
    assert not written, f"programs written: {sorted(map(str, written))}\n{shown}"
