"""ABB RAPID post-processor: ``.mod`` modules plus a ``.pgf`` program file.

Each trajectory waypoint becomes one ``MoveAbsJ`` with an inline jointtarget.
The first move goes from wherever the robot is to the start at the profile's
``approach_speed`` and stops (``fine``); every later move carries the
trajectory's duration between consecutive waypoints in ``\\T:=`` (rounded up
to 0.1 ms, so a move is never faster than planned) with the profile zone;
the last move is ``fine``. Joint values: 1e-4 deg, 1e-3 mm; 9E9 for axes the
profile leaves unconnected. Programs longer than ``lines_per_module`` moves
are split into modules ``<NAME>_001 ...``, each with one routine
``<NAME>_001_run``, and the main module ``<NAME>`` loads, runs (late binding
``%"<NAME>_001_run"%;``) and unloads them in turn.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camtool import __version__
from camtool.errors import BadInput
from camtool.profiles import require_full_map
from camtool.transforms import matrix_from_xyz_rpy, quaternion_wxyz_from_matrix

from .base import chunks, sanitise_name
from .check import check_motion, resolution_tol

RESERVED = frozenset("""ALIAS AND BACKWARD CASE CONNECT CONST DEFAULT DIV DO ELSE ELSEIF ENDFOR ENDFUNC ENDIF
ENDMODULE ENDPROC ENDRECORD ENDTEST ENDTRAP ENDWHILE ERROR EXIT FALSE FOR FROM FUNC GOTO IF INOUT LOCAL MOD
MODULE NOSTEPIN NOT NOVIEW OR PERS PROC RAISE READONLY RECORD RETRY RETURN STEP SYSMODULE TASK TEST THEN TO
TRAP TRUE TRYNEXT UNDO VAR VIEWONLY WHILE WITH XOR""".split())
# Data the controller's BASE module already declares: never redeclare them.
BUILTIN_DATA = frozenset({"tool0", "wobj0", "load0"})
RAX = tuple(f"rax_{i}" for i in range(1, 7))
EAX = tuple(f"eax_{c}" for c in "abcdef")
ZONES = ("fine", "z0", "z1", "z5", "z10", "z15", "z20", "z30", "z40", "z50", "z60", "z80", "z100",
         "z150", "z200")
SPEEDS = ("v5", "v10", "v20", "v30", "v40", "v50", "v60", "v80", "v100", "v150", "v200", "v300", "v400",
          "v500", "v600", "v800", "v1000", "v1500", "v2000", "v2500", "v3000", "v4000", "v5000", "v6000",
          "v7000", "vmax")
NOT_CONNECTED = 9e9
T_RESOLUTION_S = 1e-4

_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
MOVE_RE = re.compile(
    r"^\s*MoveAbsJ\s+\[\[(?P<rax>[^\[\]]*)\],\[(?P<eax>[^\[\]]*)\]\](?:\\NoEOffs)?\s*,\s*(?P<speed>\w+)"
    r"\s*(?:\\T:=(?P<t>" + _NUM + r"))?\s*,\s*(?P<zone>\w+)\s*,\s*(?P<tool>\w+)\s*(?:\\WObj:=(?P<wobj>\w+))?\s*;$")
LOAD_RE = re.compile(r'^\s*Load\s+\\Dynamic\s*,\s*"(?P<path>[^"]+)"\s*;$')
UNLOAD_RE = re.compile(r'^\s*UnLoad\s+"(?P<path>[^"]+)"\s*;$')
CALL_RE = re.compile(r'^\s*%"(?P<proc>[^"]+)"%\s*;$')
MODULE_RE = re.compile(r"^MODULE\s+(?P<name>\w+)\s*$")
PROC_RE = re.compile(r"^\s*PROC\s+(?P<name>\w+)\s*\(\s*\)\s*$")
PERS_RE = re.compile(r"^\s*(?:TASK\s+)?(?:PERS|CONST|VAR)\s+(?P<type>\w+)\s+(?P<name>\w+)\s*:=.*;$")


def rapid_identifier(raw: str, max_len: int = 32) -> tuple[str, str]:
    """A legal RAPID identifier (<= 32 chars, leading letter, not reserved) and a note if changed."""
    return sanitise_name(raw, max_len=max_len, reserved=RESERVED | BUILTIN_DATA, what="RAPID identifier")


def fmt_num(x: float, decimals: int) -> str:
    """Fixed-point number without a negative zero."""
    s = f"{x:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0 else s


def fmt_t(dt_s: float) -> str:
    """A \\T duration rounded up to 0.1 ms (never faster than planned), at least 0.1 ms."""
    ticks = max(1, math.ceil(dt_s / T_RESOLUTION_S - 1e-6))
    return f"{ticks * T_RESOLUTION_S:.4f}"


@dataclass
class Move:
    """One parsed MoveAbsJ: line number, axis values, speed, duration (s or None), zone, tool, wobj."""

    line: int
    rax: list[float]
    eax: list[float]
    speed: str
    t_s: float | None
    zone: str
    tool: str
    wobj: str | None


@dataclass
class ModuleText:
    """What the reader finds in one .mod file."""

    name: str = ""
    procs: list[str] = field(default_factory=list)
    data: dict[str, str] = field(default_factory=dict)  # name -> type
    moves: list[Move] = field(default_factory=list)
    loads: list[tuple[int, str]] = field(default_factory=list)
    calls: list[tuple[int, str]] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)


def _all_finite(text: str) -> bool:
    """False when a data value holds nan / inf or a number too large for a float."""
    for tok in re.split(r"[\s,\[\]]+", text):
        try:
            if not math.isfinite(float(tok)):
                return False
        except ValueError:  # TRUE, "", a name: not a number
            pass
    return True


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split(",")] if text.strip() else []


def parse_module(path: Path) -> ModuleText:
    """Parse a camtool-style RAPID module; structural problems are collected, not raised."""
    m = ModuleText()
    try:
        text = path.read_text(encoding="latin-1")
    except OSError as exc:
        m.problems.append(f"{path}: cannot read ({exc})")
        return m
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines = lines[:-1]
    else:
        m.problems.append(f"{path}:{len(lines)}: no newline at end of file")
    if "\r" in text:
        m.problems.append(f"{path}: CR characters found (RAPID modules use LF line ends here)")
    depth = 0
    for n, line in enumerate(lines, 1):
        where = f"{path}:{n}"
        if line != line.rstrip():
            m.problems.append(f"{where}: trailing white space")
        if "\t" in line:
            m.problems.append(f"{where}: tab character")
        s = line.strip()
        if not s or s.startswith("!"):
            continue
        if s.startswith("%%%"):
            m.problems.append(f"{where}: '%%%' header is not allowed in a .mod file")
        elif (mm := MODULE_RE.match(line)):
            if m.name:
                m.problems.append(f"{where}: second MODULE in one file")
            m.name = mm.group("name")
        elif s == "ENDMODULE":
            if depth:
                m.problems.append(f"{where}: ENDMODULE inside a PROC")
            if n != len(lines):
                m.problems.append(f"{where}: text after ENDMODULE")
        elif (pm := PROC_RE.match(line)):
            if depth:
                m.problems.append(f"{where}: PROC inside a PROC")
            depth += 1
            m.procs.append(pm.group("name"))
        elif s == "ENDPROC":
            if not depth:
                m.problems.append(f"{where}: ENDPROC without PROC")
            depth = max(0, depth - 1)
        elif (dm := PERS_RE.match(line)) and not depth:
            m.data[dm.group("name")] = dm.group("type")
            if not _all_finite(line.split(":=", 1)[1]):
                m.problems.append(f"{where}: {dm.group('name')} holds a value that is not a finite number")
        elif s.startswith("MoveAbsJ"):
            mv = MOVE_RE.match(line)
            if not mv or not depth:
                m.problems.append(f"{where}: malformed MoveAbsJ" + ("" if mv else f": {s[:60]}"))
                continue
            try:
                rax, eax = _floats(mv.group("rax")), _floats(mv.group("eax"))
            except ValueError:
                m.problems.append(f"{where}: jointtarget values must be numbers")
                continue
            if not all(math.isfinite(v) for v in rax + eax):
                m.problems.append(f"{where}: jointtarget values must be finite numbers")
                continue
            if len(rax) != 6 or len(eax) != 6:
                m.problems.append(f"{where}: jointtarget needs 6 robot and 6 external values, found "
                                  f"{len(rax)} and {len(eax)}")
                continue
            t = mv.group("t")
            if t and not math.isfinite(float(t)):
                m.problems.append(f"{where}: \\T must be a finite number of seconds, found {t}")
                continue
            m.moves.append(Move(n, rax, eax, mv.group("speed"), float(t) if t else None,
                                mv.group("zone"), mv.group("tool"), mv.group("wobj")))
        elif (lm := LOAD_RE.match(line)) and depth:
            m.loads.append((n, lm.group("path")))
        elif UNLOAD_RE.match(line) and depth:
            pass
        elif (cm := CALL_RE.match(line)) and depth:
            m.calls.append((n, cm.group("proc")))
        else:
            m.problems.append(f"{where}: unrecognised statement: {s[:60]}")
    if not m.name:
        m.problems.append(f"{path}: no MODULE line")
    if depth:
        m.problems.append(f"{path}: PROC without ENDPROC")
    if not lines or lines[-1].strip() != "ENDMODULE":
        m.problems.append(f"{path}: the module does not end with ENDMODULE")
    return m


def read_pgf(path: Path) -> list[str]:
    """Module file names listed in a .pgf program file."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as exc:
        raise BadInput(f"{path}: not a readable program file ({exc})") from None
    if root.tag != "Program":
        raise BadInput(f"{path}: root element is <{root.tag}>, expected <Program>")
    return [(e.text or "").strip() for e in root.findall("Module")]


def program_modules(path: Path) -> list[tuple[Path, ModuleText]]:
    """The modules of a program in run order: a .pgf's modules, then each Load of a main
    module (resolved by file name in the same folder)."""
    path = Path(path)
    mods = [path.parent / Path(n).name for n in read_pgf(path)] if path.suffix.lower() == ".pgf" else [path]
    out = []
    for mp in mods:
        mt = parse_module(mp)
        out.append((mp, mt))
        for _n, load in mt.loads:
            part = mp.parent / re.split(r"[/\\:]", load)[-1]
            out.append((part, parse_module(part)))
    return out


class RapidPost:
    """ABB RAPID writer and reader (see module doc)."""

    name = "rapid"
    extension = ".mod"
    extensions = (".pgf", ".mod")  # every file type it writes; `camtool check` finds the format by these
    requires_profile = True
    options_schema = {
        "lines_per_module": (int, 5000, "Moves per module; longer programs are split into modules run by a main module."),
        "zone": (str, "z1", "Zone of the timed moves (the first and last moves are always fine)."),
        "speed": (str, "v1000", "Speed data of the timed moves (their duration comes from \\T)."),
        "approach_speed": (str, "v100", "Speed data of the first move, from wherever the robot is to the start."),
        "module_dir": (str, "HOME:", "Controller folder the main module loads split modules from."),
    }

    def validate_profile(self, profile, robot) -> None:
        """BadInput unless the axis map fits RAPID (rax_1..6, eax_a..f, every joint once)."""
        require_full_map(profile, robot)
        for a in profile.axes:
            if a.axis not in RAX + EAX:
                raise BadInput(f"{profile.source}: axes.{a.joint}.axis: expected one of rax_1..rax_6, "
                               f"eax_a..eax_f, found {a.axis!r}")
        o = profile.options
        if o["zone"] not in ZONES:
            raise BadInput(f"{profile.source}: options.zone: expected one of {', '.join(ZONES)}, found {o['zone']!r}")
        for k in ("speed", "approach_speed"):
            if o[k] not in SPEEDS:
                raise BadInput(f"{profile.source}: options.{k}: expected one of v5 .. v7000, vmax, found {o[k]!r}")
        if o["lines_per_module"] < 1:
            raise BadInput(f"{profile.source}: options.lines_per_module: expected an integer >= 1")

    # --- writing ---------------------------------------------------------------------------

    def _jointtarget(self, axes: dict[str, np.ndarray], units: dict[str, str], k: int) -> str:
        def val(name):
            if name not in axes:
                return "9E9"
            return fmt_num(axes[name][k], 3 if units[name] == "mm" else 4)
        return f"[[{','.join(val(a) for a in RAX)}],[{','.join(val(a) for a in EAX)}]]"

    def write(self, trajectory, robot, profile, outdir: Path) -> list[Path]:
        """Write ``<NAME>.pgf`` and ``<NAME>.mod`` (plus ``<NAME>_NNN.mod`` parts when split)."""
        self.validate_profile(profile, robot)
        outdir = Path(outdir)
        o = profile.options
        name, _ = rapid_identifier(profile.program_name, 24)
        tool, _ = rapid_identifier(profile.tool["name"])
        wobj, _ = rapid_identifier(profile.wobj["name"])
        axes = profile.to_axes(np.asarray(trajectory.q, float), robot)
        units = {a.axis: a.unit for a in profile.axes}
        t = np.asarray(trajectory.t_s, float)
        moves = []
        for k in range(len(t)):
            jt = self._jointtarget(axes, units, k)
            if k == 0:
                moves.append(f"MoveAbsJ {jt}, {o['approach_speed']}, fine, {tool} \\WObj:={wobj};")
            else:
                zone = "fine" if k == len(t) - 1 else o["zone"]
                moves.append(f"MoveAbsJ {jt}, {o['speed']} \\T:={fmt_t(t[k] - t[k - 1])}, {zone}, {tool} \\WObj:={wobj};")
        header = [f"! Generated by camtool {__version__} for robot {robot.name}: {len(t)} moves, "
                  f"{trajectory.duration_s:.3f} s",
                  f"! Profile: {Path(profile.source).name}. Units: deg, mm, s; 9E9 = axis not connected."]
        decl = [self._tooldata(tool, profile.tool), self._wobjdata(wobj, profile.wobj)]
        parts = chunks(len(moves), o["lines_per_module"])
        files: dict[str, list[str]] = {}
        if len(parts) == 1:
            files[name] = self._module(name, header, decl, "main", moves)
        else:
            body = []
            for i, r in enumerate(parts, 1):
                part = f"{name}_{i:03d}"
                where = f"{o['module_dir'].rstrip('/')}/{part}.mod"
                body += [f'Load \\Dynamic, "{where}";', f'%"{part}_run"%;', f'UnLoad "{where}";']
                files[part] = self._module(part, [f"! Part {i} of {len(parts)} of {name}: moves "
                                                  f"{r.start + 1}..{r.stop}"], [], f"{part}_run",
                                           [moves[k] for k in r])
            files = {name: self._module(name, header + [f"! Runs {len(parts)} modules in turn."], decl, "main",
                                        body), **files}
        written = [outdir / f"{name}.pgf"]
        written[0].write_bytes(("<?xml version=\"1.0\" encoding=\"ISO-8859-1\" ?>\n<Program>\n"
                                f"  <Module>{name}.mod</Module>\n</Program>\n").encode("ascii"))
        for mod, lines in files.items():
            p = outdir / f"{mod}.mod"
            p.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
            written.append(p)
        return written

    @staticmethod
    def _module(name, header, decl, proc, body) -> list[str]:
        return ([f"MODULE {name}"] + [f"  {h}" for h in header] + [f"  {d}" for d in decl]
                + [f"  PROC {proc}()"] + [f"    {b}" for b in body] + ["  ENDPROC", "ENDMODULE"])

    @staticmethod
    def _quat(rpy_deg) -> str:
        q = quaternion_wxyz_from_matrix(matrix_from_xyz_rpy([0, 0, 0], rpy_deg)[:3, :3])
        return ",".join(fmt_num(v, 6) for v in q)

    def _tooldata(self, name: str, tool: dict) -> str:
        xyz = ",".join(fmt_num(v, 3) for v in tool["tcp_xyz_mm"])
        cog = ",".join(fmt_num(v, 3) for v in tool["cog_mm"])
        mass = fmt_num(max(float(tool["mass_kg"]), 0.001), 3)  # the controller refuses a zero mass
        return f"PERS tooldata {name}:=[TRUE,[[{xyz}],[{self._quat(tool['tcp_rpy_deg'])}]],[{mass},[{cog}],[1,0,0,0],0,0,0]];"

    def _wobjdata(self, name: str, wobj: dict) -> str:
        xyz = ",".join(fmt_num(v, 3) for v in wobj["xyz_mm"])
        return f'PERS wobjdata {name}:=[FALSE,TRUE,"",[[{xyz}],[{self._quat(wobj["rpy_deg"])}]],[[0,0,0],[1,0,0,0]]];'

    # --- reading ---------------------------------------------------------------------------

    def read(self, path: Path, robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """(durations_s, q): each MoveAbsJ's \\T (NaN when absent) and its target in rad / mm,
        following a .pgf and the Loads of a main module."""
        moves = [mv for _p, mt in program_modules(Path(path)) for mv in mt.moves]
        return self.moves_to_arrays(moves, robot, profile)

    @staticmethod
    def moves_to_arrays(moves: list[Move], robot, profile) -> tuple[np.ndarray, np.ndarray]:
        """Durations (s, NaN when absent) and joint values (rad / mm) of parsed moves."""
        dur = np.array([np.nan if m.t_s is None else m.t_s for m in moves])
        names = RAX + EAX
        values = {a.axis: np.array([(m.rax + m.eax)[names.index(a.axis)] for m in moves]) for a in profile.axes}
        return dur, profile.from_axes(values, robot) if moves else np.zeros((0, robot.dof))

    # --- checking --------------------------------------------------------------------------

    def check(self, path: Path, robot, profile) -> list[str]:
        """Findings for a program (.pgf) or module (.mod) and the modules it loads: module /
        proc nesting (a truncated module lacks ENDPROC / ENDMODULE), statements, identifiers,
        declared tool and work object, 6 + 6 finite jointtarget values, 9E9 exactly on the
        axes the profile leaves unconnected, zones, speed data, a ``fine`` last move; then
        every value against the robot's limits and every \\T step against its speed limits
        (tolerance: the written 1e-4 deg / 1e-3 mm)."""
        path = Path(path)
        out: list[str] = []
        try:
            modules = program_modules(path)
        except BadInput as exc:
            return [str(exc)]
        if path.suffix.lower() == ".pgf" and not path.read_bytes().endswith(b"\n"):
            out.append(f"{path}: no newline at end of file")
        mapped = {a.axis for a in profile.axes}
        names = RAX + EAX
        procs = {p for _mp, mt in modules for p in mt.procs}
        declared = {n: t for _mp, mt in modules for n, t in mt.data.items()}
        entry = path.suffix.lower() == ".pgf" or "main" in modules[0][1].procs
        moves, where = [], []
        for mp, mt in modules:
            out += mt.problems
            if mt.name:
                ident, _ = rapid_identifier(mt.name)
                if ident != mt.name or len(mt.name) > 32:
                    out.append(f"{mp}: module name {mt.name!r} is not a valid RAPID identifier")
                if mt.name != mp.stem:
                    out.append(f"{mp}: module {mt.name!r} is in a file named {mp.name!r}")
            for p in mt.procs + list(mt.data):
                if rapid_identifier(p)[0] != p and p not in BUILTIN_DATA:
                    out.append(f"{mp}: {p!r} is not a valid RAPID identifier")
            for n, proc in mt.calls:
                if proc not in procs:
                    out.append(f"{mp}:{n}: %\"{proc}\"% calls a routine no loaded module defines")
            for mv in mt.moves:
                w = f"{mp}:{mv.line}"
                vals = dict(zip(names, mv.rax + mv.eax))
                for ax in names:
                    if ax in mapped and vals[ax] >= 8.9e9:
                        out.append(f"{w}: {ax} is connected (profile) but written as 9E9")
                    elif ax not in mapped and vals[ax] != NOT_CONNECTED:
                        out.append(f"{w}: {ax} is not connected (profile) and must be 9E9, found {vals[ax]}")
                if mv.zone not in ZONES:
                    out.append(f"{w}: unknown zone {mv.zone!r}")
                if mv.speed not in SPEEDS:
                    out.append(f"{w}: unknown speed data {mv.speed!r}")
                for kind, name in (("tooldata", mv.tool), ("wobjdata", mv.wobj)):
                    # a split module alone relies on the main module's declarations
                    if entry and name and name not in BUILTIN_DATA and declared.get(name) != kind:
                        out.append(f"{w}: {kind} {name!r} is not declared in the program")
                moves.append(mv)
                where.append(w)
        if entry and "main" not in modules[0][1].procs:
            out.append(f"{modules[0][0]}: the main module has no PROC main()")
        if entry and moves and moves[-1].zone != "fine":
            out.append(f"{where[-1]}: the last move must be fine, found {moves[-1].zone}")
        if not moves or out:
            if not moves and not out:
                out.append(f"{path}: no MoveAbsJ found")
            if any("connected" in f for f in out):
                return out
        dur, q = self.moves_to_arrays(moves, robot, profile)
        return out + check_motion(q, dur, robot, where, resolution_tol(robot, 1e-4, 1e-3))
