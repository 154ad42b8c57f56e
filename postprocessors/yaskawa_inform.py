"""Yaskawa INFORM post-processor: ``.JBI`` job files in pulses (ASCII, CRLF).

Each trajectory waypoint becomes one position (``C`` line for the robot RB1,
``BC`` line for a base axis BS1, ``EC`` for a station ST1; axis order from the
profile's ``RB1:k`` / ``BS1:k`` / ``ST1:k`` axis names) and one ``MOVJ``.

INFORM has no per-move duration, so the timing is approximated by VJ (a
percentage of each axis's maximum speed ``max_speed`` from the profile)::

    VJ = 100 * max_i |dv_i| / (dt * vmax_i)

where dv_i is axis i's change over the move (deg or mm) and dt the
trajectory's duration of the move. VJ is rounded *down* to 0.01 (never faster
than planned) and clipped to 0.01..100.00; a move that would need more than
100 % runs slower than planned. The first move (from wherever the robot is)
uses ``approach_vj``. ``///DATE`` comes from the ``date`` option (fixed by
default), so the same input always gives byte-identical files.

Jobs longer than ``lines_per_job`` positions are split into ``NAME_1``,
``NAME_2`` ... (each name <= ``job_name_length`` characters) and a main job
``NAME`` runs them with ``CALL JOB:...``.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.profiles import require_full_map

from .base import chunks, sanitise_name
from .check import check_motion

GROUPS = {"RB1": "C", "BS1": "BC", "ST1": "EC"}  # axis group -> position line prefix
AXIS_RE = re.compile(r"^(RB1|BS1|ST1):([1-9][0-9]*)$")
DATE_RE = re.compile(r"^\d{4}/\d{2}/\d{2} \d{2}:\d{2}$")
POS_RE = re.compile(r"^(C|BC|EC)(\d{5})=(.*)$")
MOVE_RE = re.compile(r"^(MOVJ)((?: (?:C|BC|EC)\d{5})+) VJ=(\d+\.\d{2}) PL=(\d+)$")
CALL_RE = re.compile(r"^CALL JOB:([A-Za-z0-9_]+)$")
INT_RE = re.compile(r"^-?[0-9]+$")
INT64 = (-(2 ** 63), 2 ** 63 - 1)


def job_name(raw: str, max_len: int = 8) -> tuple[str, str]:
    """A legal job name (uppercase, digits, ``_``, leading letter, <= max_len) and a note."""
    return sanitise_name(raw, max_len=max_len, upper=True, what="INFORM job name")


def vj_percent(dv: np.ndarray, dt_s: float, vmax: np.ndarray) -> float:
    """VJ (%) for one move: axis changes dv (deg / mm), duration dt (s), max speeds vmax (unit/s)."""
    need = 100.0 * float(np.max(np.abs(dv) / vmax)) / dt_s if dt_s > 0 else 100.0
    return min(100.0, max(0.01, math.floor(need * 100 + 1e-6) / 100))


def group_axes(profile) -> dict[str, list]:
    """Axis-map entries per group (RB1, BS1, ST1), in index order."""
    out: dict[str, list] = {}
    for a in profile.axes:
        m = AXIS_RE.match(a.axis)
        out.setdefault(m.group(1), []).append((int(m.group(2)), a))
    return {g: [a for _i, a in sorted(v, key=lambda x: x[0])] for g, v in sorted(out.items(), key=lambda x: list(GROUPS).index(x[0]))}


@dataclass
class JbiMove:
    """One parsed MOVJ: line number, referenced positions by prefix, VJ (%) and PL."""

    line: int
    refs: dict[str, int]
    vj: float
    pl: int


@dataclass
class JbiText:
    """What the reader finds in one .JBI file."""

    name: str = ""
    npos: list[int] = field(default_factory=list)
    tool: int | None = None
    group: list[str] = field(default_factory=list)
    pos: dict[str, list[tuple[int, list[int], int]]] = field(default_factory=lambda: {"C": [], "BC": [], "EC": []})
    moves: list[JbiMove] = field(default_factory=list)
    calls: list[tuple[int, str]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)
    bad_values: list[str] = field(default_factory=list)  # position lines whose pulses cannot be read


def parse_jbi(path: Path) -> JbiText:
    """Parse a job file; every structural problem is collected (NPOS, indices, values per
    line, references, END, CRLF, ASCII), never raised."""
    j = JbiText()
    p = f"{path}"
    try:
        raw = Path(path).read_bytes()
    except OSError as exc:
        j.problems.append(f"{p}: cannot read ({exc})")
        return j
    try:
        text = raw.decode("ascii")
    except UnicodeDecodeError as exc:
        j.problems.append(f"{p}: not ASCII (byte {exc.start})")
        text = raw.decode("latin-1")
    if not text.endswith("\r\n"):
        j.problems.append(f"{p}: the file must end with CRLF")
    lines = text.split("\r\n")
    if lines[-1] == "":
        lines = lines[:-1]
    section = ""
    for n, line in enumerate(lines, 1):
        where = f"{p}:{n}"
        if "\n" in line or "\r" in line:
            j.problems.append(f"{where}: line ending is not CRLF")
            line = line.replace("\r", "").replace("\n", "")
        if n == 1:
            if line != "/JOB":
                j.problems.append(f"{where}: expected /JOB, found {line[:40]!r}")
            continue
        if line.startswith("//NAME "):
            j.name = line[7:]
        elif line == "//POS":
            section = "pos"
        elif line == "//INST":
            section = "inst"
        elif line.startswith("///NPOS "):
            try:
                j.npos = [int(x) for x in line[8:].split(",")]
            except ValueError:
                j.problems.append(f"{where}: NPOS must be 6 integers")
            if len(j.npos) != 6:
                j.problems.append(f"{where}: NPOS must be 6 integers")
        elif line.startswith("///TOOL "):
            j.tool = int(line[8:]) if line[8:].isdigit() else None
        elif line.startswith("///GROUP1 "):
            j.group = line[10:].split(",")
        elif line in ("///POSTYPE PULSE", "///PULSE", "///ATTR SC,RW", "NOP") or line.startswith("///DATE "):
            if line.startswith("///DATE ") and not DATE_RE.match(line[8:]):
                j.problems.append(f"{where}: DATE must be yyyy/mm/dd hh:mm")
        elif line.startswith("'"):
            continue
        elif section == "pos" and (m := POS_RE.match(line)):
            cells = m.group(3).split(",")
            if not all(INT_RE.match(c) for c in cells):
                j.bad_values.append(f"{where}: pulse values must be integers")
                j.problems.append(j.bad_values[-1])
                continue
            big = next((c for c in cells if len(c.lstrip("-").lstrip("0")) > 19
                        or not INT64[0] <= int(c) <= INT64[1]), None)
            if big is not None:
                shown = big if len(big) <= 30 else big[:27] + "..."
                j.bad_values.append(f"{where}: pulse value {shown} is beyond the int64 range")
                j.problems.append(j.bad_values[-1])
                continue
            vals = [int(c) for c in cells]
            j.pos[m.group(1)].append((int(m.group(2)), vals, n))
        elif section == "inst" and (m := MOVE_RE.match(line)):
            refs = {}
            for tok in m.group(2).split():
                pre = tok.rstrip("0123456789")
                if pre in refs:
                    j.problems.append(f"{where}: {pre} given twice")
                refs[pre] = int(tok[len(pre):])
            j.moves.append(JbiMove(n, refs, float(m.group(3)), int(m.group(4))))
        elif section == "inst" and (m := CALL_RE.match(line)):
            j.calls.append((n, m.group(1)))
        elif line == "END":
            if n != len(lines):
                j.problems.append(f"{where}: text after END")
        else:
            j.problems.append(f"{where}: unrecognised line: {line[:60]}")
    if not lines or lines[-1] != "END":
        j.problems.append(f"{p}: the job does not end with END")
    if not j.name:
        j.problems.append(f"{p}: no //NAME line")
    if len(j.npos) == 6:
        for k, pre in enumerate(("C", "BC", "EC")):
            if j.npos[k] != len(j.pos[pre]):
                j.problems.append(f"{p}: NPOS says {j.npos[k]} {pre} positions, the file has {len(j.pos[pre])}")
        if any(j.npos[3:]):
            j.problems.append(f"{p}: NPOS counts P/BP/EX variables, which camtool never writes")
    elif not j.npos:
        j.problems.append(f"{p}: no ///NPOS line")
    order = [ln for pre in ("C", "BC", "EC") for (_i, _v, ln) in j.pos[pre]]
    if order != sorted(order):
        j.problems.append(f"{p}: positions must come as all C lines, then BC, then EC")
    for pre, items in j.pos.items():
        idx = [i for i, _v, _l in items]
        if idx != list(range(len(idx))):
            bad = next(k for k, i in enumerate(idx) if i != k)
            j.problems.append(f"{p}:{items[bad][2]}: {pre} indices must be contiguous from 00000")
        counts = {len(v) for _i, v, _l in items}
        if len(counts) > 1:
            j.problems.append(f"{p}: {pre} lines have different numbers of values ({sorted(counts)})")
    need = {"RB1": "C", "BS1": "BC", "ST1": "EC"}
    for mv in j.moves:
        for pre, i in mv.refs.items():
            if i >= len(j.pos[pre]):
                j.problems.append(f"{p}:{mv.line}: {pre}{i:05d} is not defined in //POS")
        for g in j.group:
            if g in need and need[g] not in mv.refs:
                j.problems.append(f"{p}:{mv.line}: group {g} needs a {need[g]} position on every move")
        if not 0.01 <= mv.vj <= 100.0:
            j.problems.append(f"{p}:{mv.line}: VJ={mv.vj:.2f} outside 0.01..100.00")
        if not 0 <= mv.pl <= 8:
            j.problems.append(f"{p}:{mv.line}: PL={mv.pl} outside 0..8")
    return j


def job_files(path: Path) -> list[tuple[Path, JbiText]]:
    """A job and, in run order, the jobs it CALLs (found as NAME.JBI in the same folder)."""
    path = Path(path)
    j = parse_jbi(path)
    out = [(path, j)]
    for _n, name in j.calls:
        out.append((path.parent / f"{name}.JBI", parse_jbi(path.parent / f"{name}.JBI")))
    return out


class InformPost:
    """Yaskawa INFORM writer and reader (see module doc)."""

    name = "inform"
    extension = ".JBI"
    extensions = (".JBI",)
    requires_profile = True
    options_schema = {
        "lines_per_job": (int, 2000, "Positions per job; longer programs are split into jobs run by a main job."),
        "pl": (int, 0, "Position level (blending) of the moves, 0..8; the last move is always PL=0."),
        "approach_vj": (float, 10.0, "VJ (%) of the first move, from wherever the robot is to the start."),
        "date": (str, "2000/01/01 00:00", "///DATE written to every job (fixed, so output is reproducible)."),
        "job_name_length": (int, 8, "Longest job name; 8 is safe, newer controllers take 32."),
    }

    def validate_profile(self, profile, robot) -> None:
        """BadInput unless the axis map fits INFORM: every joint on RB1/BS1/ST1 with pulses and max_speed."""
        require_full_map(profile, robot)
        for a in profile.axes:
            where = f"{profile.source}: axes.{a.joint}"
            if not AXIS_RE.match(a.axis):
                raise BadInput(f"{where}.axis: expected RB1:n, BS1:n or ST1:n, found {a.axis!r}")
            if a.pulses is None:
                raise BadInput(f"{where}.pulses: missing (pulses per {a.unit} of this axis, from the controller's parameters)")
            if a.max_speed is None:
                raise BadInput(f"{where}.max_speed: missing (the axis's maximum speed in {a.unit}/s, needed for VJ)")
        groups = group_axes(profile)
        if "RB1" not in groups:
            raise BadInput(f"{profile.source}: axes: no joint is mapped to the robot group RB1")
        for g, axes in groups.items():
            idx = sorted(int(AXIS_RE.match(a.axis).group(2)) for a in axes)
            if idx != list(range(1, len(idx) + 1)):
                raise BadInput(f"{profile.source}: axes: {g} axes must be numbered 1..{len(idx)}, found {idx}")
        o = profile.options
        if not 0 <= o["pl"] <= 8:
            raise BadInput(f"{profile.source}: options.pl: expected 0..8, found {o['pl']}")
        if not 0.01 <= o["approach_vj"] <= 100:
            raise BadInput(f"{profile.source}: options.approach_vj: expected 0.01..100, found {o['approach_vj']}")
        if not DATE_RE.match(o["date"]):
            raise BadInput(f"{profile.source}: options.date: expected 'yyyy/mm/dd hh:mm', found {o['date']!r}")
        if o["lines_per_job"] < 1:
            raise BadInput(f"{profile.source}: options.lines_per_job: expected an integer >= 1")
        if not 3 <= o["job_name_length"] <= 32:
            raise BadInput(f"{profile.source}: options.job_name_length: expected 3..32")

    @staticmethod
    def to_pulses(profile, robot, q_native: np.ndarray) -> dict[str, np.ndarray]:
        """Pulses (int64, M x n) per group for joint values (rad / mm)."""
        axes = profile.to_axes(q_native, robot)
        return {g: np.stack([np.round(axes[a.axis] * a.pulses).astype(np.int64) + a.zero_pulses for a in ax], axis=1)
                for g, ax in group_axes(profile).items()}

    @staticmethod
    def from_pulses(profile, robot, pulses: dict[str, np.ndarray]) -> np.ndarray:
        """Joint values (rad / mm) from pulses per group."""
        values = {}
        for g, ax in group_axes(profile).items():
            for k, a in enumerate(ax):  # in float: no int64 wrap-around for absurd pulse values
                values[a.axis] = (np.asarray(pulses[g][:, k], float) - float(a.zero_pulses)) / a.pulses
        return profile.from_axes(values, robot)

    def write(self, trajectory, robot, profile, outdir: Path) -> list[Path]:
        """Write ``NAME.JBI`` (plus ``NAME_1.JBI`` ... parts and a main job when split)."""
        self.validate_profile(profile, robot)
        o = profile.options
        outdir = Path(outdir)
        name, _ = job_name(profile.program_name, o["job_name_length"])
        q = np.asarray(trajectory.q, float)
        t = np.asarray(trajectory.t_s, float)
        pulses = self.to_pulses(profile, robot, q)
        groups = group_axes(profile)
        axes = profile.to_axes(q, robot)
        order = [a for ax in groups.values() for a in ax]
        vmax = np.array([a.max_speed for a in order])
        values = np.stack([axes[a.axis] for a in order], axis=1)
        vj = [o["approach_vj"]] + [vj_percent(values[k] - values[k - 1], t[k] - t[k - 1], vmax)
                                   for k in range(1, len(t))]
        parts = chunks(len(t), o["lines_per_job"])
        header = dict(tool=profile.tool["number"], date=o["date"], group=",".join(groups))
        files: dict[str, list[str]] = {}
        if len(parts) == 1:
            files[name] = self._job(name, parts[0], pulses, vj, o["pl"], len(t), header)
        else:
            names = []
            for i, r in enumerate(parts, 1):
                s = f"_{i}"
                part = name[:o["job_name_length"] - len(s)] + s
                names.append(part)
                files[part] = self._job(part, r, pulses, vj, o["pl"], len(t), header)
            main = ["/JOB", f"//NAME {name}", "//POS", "///NPOS 0,0,0,0,0,0", "//INST", f"///DATE {o['date']}",
                    "///ATTR SC,RW", f"///GROUP1 {header['group']}", "NOP"] + [f"CALL JOB:{n}" for n in names] + ["END"]
            files = {name: main, **files}
        written = []
        for job, lines in files.items():
            p = outdir / f"{job}.JBI"
            p.write_bytes(("\r\n".join(lines) + "\r\n").encode("ascii"))
            written.append(p)
        return written

    @staticmethod
    def _job(name, r: range, pulses, vj, pl, n_total, header) -> list[str]:
        lines = ["/JOB", f"//NAME {name}", "//POS"]
        counts = [len(r) if g in pulses else 0 for g in GROUPS]
        lines += [f"///NPOS {counts[0]},{counts[1]},{counts[2]},0,0,0", f"///TOOL {header['tool']}",
                  "///POSTYPE PULSE", "///PULSE"]
        for g, pre in GROUPS.items():
            if g in pulses:
                lines += [f"{pre}{i:05d}=" + ",".join(str(int(v)) for v in pulses[g][k]) for i, k in enumerate(r)]
        lines += ["//INST", f"///DATE {header['date']}", "///ATTR SC,RW", f"///GROUP1 {header['group']}", "NOP"]
        for i, k in enumerate(r):
            refs = " ".join(f"{pre}{i:05d}" for g, pre in GROUPS.items() if g in pulses)
            lines.append(f"MOVJ {refs} VJ={vj[k]:.2f} PL={0 if k in (0, n_total - 1) else pl}")
        return lines + ["END"]

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """(durations_s, q): per MOVJ the duration implied by VJ and the profile's max speeds
        (NaN for the first move) and the target in rad / mm; follows CALL JOB."""
        moves, pulses = [], {g: [] for g in GROUPS}
        for _p, j in job_files(Path(path)):
            if j.bad_values:
                raise BadInput(j.bad_values[0])
            for mv in j.moves:
                moves.append(mv)
                for g, pre in GROUPS.items():
                    if pre in mv.refs and mv.refs[pre] < len(j.pos[pre]):
                        pulses[g].append(j.pos[pre][mv.refs[pre]][1])
        return self.moves_to_arrays(moves, pulses, robot, profile)

    def moves_to_arrays(self, moves, pulses, robot, profile):
        """Durations (s) and joint values (rad / mm) of parsed moves and their pulses."""
        groups = group_axes(profile)
        arr = {}
        for g, ax in groups.items():
            try:
                a = np.array(pulses.get(g, []), dtype=np.int64).reshape(-1, len(ax)) if pulses.get(g) else None
            except OverflowError:
                raise BadInput(f"a {GROUPS[g]} pulse value is beyond the int64 range") from None
            except ValueError:
                a = None
            if a is None or len(a) != len(moves) or a.shape[1] != len(ax):
                raise BadInput(f"job positions do not match the profile's {g} axes "
                               f"({len(ax)} values per {GROUPS[g]} line expected)")
            arr[g] = a
        q = self.from_pulses(profile, robot, arr) if moves else np.zeros((0, robot.dof))
        order = [a for ax in groups.values() for a in ax]
        vmax = np.array([a.max_speed for a in order])
        values = np.stack([profile.to_axes(q, robot)[a.axis] for a in order], axis=1) if moves else np.zeros((0, 1))
        dur = np.full(len(moves), np.nan)
        for k in range(1, len(moves)):
            dur[k] = float(np.max(np.abs(values[k] - values[k - 1]) / vmax)) * 100.0 / moves[k].vj
        return dur, q

    # --- checking --------------------------------------------------------------------------

    def check(self, path: Path, robot, profile) -> list[str]:
        """Findings for a job and the jobs it CALLs: NPOS counts against the positions (a
        truncated job has fewer, and no END), contiguous indices, integer pulses within
        int64, values per line, references, END, CRLF, ASCII, group and names; then every
        value against the robot's limits and every move's speed against the robot's speed
        limits (tolerance: one pulse). A move's duration is the controller's: the governing
        axis at VJ % of the profile's ``max_speed`` (docs/controllers.md); the resulting
        axis speeds must stay within ``robot.limits.velocity``, whatever the profile says."""
        path = Path(path)
        out: list[str] = []
        groups = group_axes(profile)
        want_group = list(groups)
        max_len = profile.options.get("job_name_length", 8)
        moves, pulses, where = [], {g: [] for g in GROUPS}, []
        consistent = True
        for jp, j in job_files(path):
            out += j.problems
            consistent &= not j.problems
            if j.name:
                if job_name(j.name, 32)[0] != j.name or len(j.name) > max_len:
                    out.append(f"{jp}: job name {j.name!r} is not valid (uppercase, digits, _, leading letter, "
                               f"<= {max_len} characters)")
                if j.name != jp.stem:
                    out.append(f"{jp}: job {j.name!r} is in a file named {jp.name!r}")
            if j.group and j.group != want_group:
                out.append(f"{jp}: ///GROUP1 {','.join(j.group)} does not match the profile ({','.join(want_group)})")
                consistent = False
            for g, ax in groups.items():
                pre = GROUPS[g]
                for _i, vals, ln in j.pos[pre]:
                    if len(vals) != len(ax):
                        out.append(f"{jp}:{ln}: {pre} line has {len(vals)} values, group {g} has {len(ax)} axes")
                        consistent = False
            for mv in j.moves:
                moves.append(mv)
                where.append(f"{jp}:{mv.line}")
                for g, pre in GROUPS.items():
                    if g in groups and pre in mv.refs and mv.refs[pre] < len(j.pos[pre]):
                        pulses[g].append(j.pos[pre][mv.refs[pre]][1])
        if not consistent or not moves:
            if not moves and not out:
                out.append(f"{path}: no MOVJ found")
            return out
        try:
            dur, q = self.moves_to_arrays(moves, pulses, robot, profile)
        except BadInput as exc:
            return out + [f"{path}: {exc}"]
        tol = np.zeros(robot.dof)
        for a in (a for ax in groups.values() for a in ax):
            i = robot.joint_names.index(a.joint)
            step = 1.0 / a.pulses
            tol[i] = step if robot.prismatic[i] else np.radians(step)
        return out + check_motion(q, dur, robot, where, tol + 1e-9)
