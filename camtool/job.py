"""Job files (TOML): schema, defaults and validation with precise messages.

A job has the sections ``workpiece``, ``fit``, ``raster``, ``robot``, ``cell``,
``tool``, ``planner``, ``timing``, ``task`` and ``post``. Every key has a default
(``SCHEMA``); docs/job-file.md is generated from it (``python -m
camtool.job --markdown``) and a test keeps the two in step.

Errors name the file, the key path, what was expected and what was found::

    job.toml: raster.step_over_mm: expected a number > 0, found -5
"""
from __future__ import annotations

import difflib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .errors import BadInput


MAX_LENGTH_MM = 1e6   # no length of a robot cell is longer than 1 km
MAX_ANGLE_DEG = 3600.0  # no angle of a job is more than ten turns


def _closest(word: str, known) -> str:
    """ "; did you mean X?" for the closest known name, or ""."""
    match = difflib.get_close_matches(word, list(known), n=1, cutoff=0.6)
    return f"; did you mean {match[0]!r}?" if match else ""


@dataclass(frozen=True)
class Key:
    """One job-file key: its kind, default, doc line and optional check."""

    kind: str  # float | int | str | bool | vec3 | floats | strs | table
    default: Any
    doc: str
    choices: tuple = ()
    check: Callable[[Any], bool] | None = None
    expect: str = ""  # wording of the check for error messages


def _pos(doc, default, unit="", most=None):
    if most is None:
        return Key("float", default, doc, check=lambda x: x > 0, expect=f"a number > 0{unit}")
    return Key("float", default, doc, check=lambda x: 0 < x <= most, expect=f"a number in (0, {most:g}]{unit}")


def _nonneg(doc, default, most=None):
    if most is None:
        return Key("float", default, doc, check=lambda x: x >= 0, expect="a number >= 0")
    return Key("float", default, doc, check=lambda x: 0 <= x <= most, expect=f"a number in 0..{most:g}")


def _angle89(doc):
    return Key("float", 0.0, doc, check=lambda x: -89 <= x <= 89, expect="an angle within -89..89 deg")


SCHEMA: dict[str, dict[str, Key]] = {
    "workpiece": {
        "file": Key("str", "", "Mesh (STL, OBJ, PLY, OFF, GLB) or point cloud (PLY, PCD, XYZ, CSV, TXT); relative to the job file."),
        "units": Key("str", "mm", "Length unit of the file; everything becomes mm.", choices=("mm", "m", "in")),
        "drop_nonfinite": Key("bool", False, "Drop points (and the triangles using them) with NaN, infinite or damaged coordinates, with a warning giving the count, instead of refusing the file."),
        "sample_points": Key("int", 100000, "Points sampled (area-weighted) from a mesh.", check=lambda x: 100 <= x <= 5_000_000, expect="an integer in 100..5000000"),
        "normal_neighbours": Key("int", 30, "Neighbours used to estimate point-cloud normals.", check=lambda x: 3 <= x <= 1000, expect="an integer in 3..1000"),
    },
    "fit": {
        "model": Key("str", "auto", "Surface model; auto takes the one with most inliers (a huge sphere counts as a plane).", choices=("auto", "plane", "sphere")),
        "threshold_mm": _pos("RANSAC inlier distance.", 0.5, " mm"),
        "iterations": Key("int", 1000, "RANSAC hypotheses per model.", check=lambda x: 1 <= x <= 100_000, expect="an integer in 1..100000"),
        "min_inlier_ratio": Key("float", 0.2, "Smallest inlier share a model must reach.", check=lambda x: 0 < x <= 1, expect="a number in (0, 1]"),
        "seed": Key("int", 0, "Random seed: the same seed gives the same fit.", check=lambda x: 0 <= x < 2**63, expect="an integer >= 0"),
        "boundary_cell_mm": _pos("Cell size of the occupancy image used to find the boundary.", 2.0, " mm"),
        "close_gaps_mm": _nonneg("Gaps in the material up to this width are closed before contours are taken.", 6.0),
        "simplify_mm": _nonneg("Boundary polygons are simplified to this tolerance.", 0.5),
    },
    "raster": {
        "step_over_mm": Key("float", 10.0, "Distance between rows, measured on the surface (geodesic on a sphere).", check=lambda x: 0.1 <= x <= 10_000, expect="a number in 0.1..10000 mm"),
        "pitch_mm": Key("float", 5.0, "Spacing of points along a row, measured on the surface.", check=lambda x: 0.1 <= x <= 10_000, expect="a number in 0.1..10000 mm"),
        "angle_deg": Key("float", 0.0, "Row direction in the (u, v) domain, from the u axis.", check=lambda x: -360 <= x <= 360, expect="an angle within -360..360 deg"),
        "lead_mm": _nonneg("Lead-in / lead-out length beyond the boundary at each segment end (the shortest; see lead_auto).", 20.0),
        "lead_auto": Key("bool", True, "Lengthen the leads of every row to what the ramps to and from the feed need, so that the tool is at the feed at the first work point and until the last: after a first plan, the length each run's ramps need is computed from the joint speed, acceleration and jerk limits, the feed and the planned joint path; when it is longer than lead_mm, the path is rastered again with that lead (5 % longer, rounded up to whole mm, at most lead_max_mm) and planned again (docs/timing.md)."),
        "lead_max_mm": _pos("Longest lead that lead_auto may choose.", 100.0, " mm", 10_000),
        "clearance_mm": _nonneg("Lift of lead and transition points along the surface normal (the leads rise to it as the cube of the distance from the work, leaving the surface without a kink).", 0.0),
        "self_motion_lift_mm": _nonneg("The self-motion zone between rows runs at least this far off the surface (a sine arc along the normal), so the transition never cuts into the part: on a convex part a chord between two surface points dips below the surface.", 5.0),
        "transition_points": Key("int", 5, "Poses in each self-motion zone between segments.", check=lambda x: 2 <= x <= 1000, expect="an integer in 2..1000"),
        "tool_x": Key("str", "fixed", "Tool x axis: a fixed world direction, or the travel direction.", choices=("fixed", "travel")),
        "tool_x_world": Key("vec3", [0.0, 0.0, 1.0], "World direction the tool x axis follows when tool_x = 'fixed'."),
        "lead_deg": _angle89("Lead angle: tilt of the tool about its y axis, in the travel direction."),
        "tilt_deg": _angle89("Side-tilt angle: tilt of the tool about the travel direction."),
        "free_spin": Key("bool", False, "Rotation about tool z is free (symmetric tools); the planner may use it as redundancy."),
    },
    "robot": {
        "name": Key("str", "seed8", "Built-in robot (seed8, irb2400, irb2400_paper, sia20) or a .toml / .urdf file."),
        "params": Key("table", {}, "Named lengths of a parametric robot, in mm (seed8: L1, L2, L3, L4)."),
        "home_deg": Key("floats", [], "Start configuration (deg, mm for prismatic joints); empty = found by the planner."),
    },
    "cell": {
        "base_xyz_mm": Key("vec3", [0.0, 0.0, 0.0], "Robot base position in the world frame."),
        "base_rpy_deg": Key("vec3", [0.0, 0.0, 0.0], "Robot base orientation (fixed-axis roll, pitch, yaw)."),
        "workpiece_xyz_mm": Key("vec3", [0.0, 0.0, 0.0], "Workpiece frame position in the world frame."),
        "workpiece_rpy_deg": Key("vec3", [0.0, 0.0, 0.0], "Workpiece frame orientation (fixed-axis roll, pitch, yaw)."),
        "obstacles": Key("obstacles", [], "Fixtures, tables, walls: `[[cell.obstacles]]` tables, each with `name`, exactly one shape (`mesh` = a file with `units`, its convex hull is used; `box_mm = [x, y, z]` edge lengths, centred; `cylinder_mm = [radius, length]` along its z, centred; `sphere_mm = radius`), `xyz_mm` and `rpy_deg` (its centre / mesh origin) in `frame` = \"world\" or \"workpiece\" (a fixture that moves with the part). Every robot and tool body keeps cell.clearance_mm from each, on work too (docs/motion-check.md)."),
        "floor_z_mm": Key("float", None, "A floor (world z of its top); none when not given. Robot bodies fixed to the base stand on it and are not checked against it."),
        "clearance_mm": Key("float", 5.0, "Clearance every robot and tool body keeps from the obstacles, the floor and the robot's own links (pairs the allowed-collision matrix does not allow), everywhere.", check=lambda x: 0 <= x <= 1000, expect="a number in 0..1000 mm"),
        "allow_collision": Key("pairs", [], "Body pairs added to the robot's allowed-collision matrix, e.g. [[\"j2\", \"j4\"]] (report.json: motion_check.cell lists the bodies and the matrix)."),
        "check_collision": Key("pairs", [], "Body pairs removed from the allowed-collision matrix (checked although the matrix allows them)."),
    },
    "tool": {
        "name": Key("str", "tool0", "Tool name written to controller programs."),
        "tcp_xyz_mm": Key("vec3", [0.0, 0.0, 0.0], "Tool centre point in the flange frame."),
        "tcp_rpy_deg": Key("vec3", [0.0, 0.0, 0.0], "Tool frame orientation in the flange frame."),
        "mass_kg": _nonneg("Tool mass for controller tool data.", 1.0, 10_000),
        "mesh": Key("str", "", "Collision shape of the tool: a mesh file in the flange frame (its convex hull is used); empty = a cylinder of check.tool_radius_mm from the flange to the TCP."),
        "mesh_units": Key("str", "mm", "Length unit of tool.mesh.", choices=("mm", "m", "in")),
    },
    "planner": {
        "method": Key("str", "seed", "seed = CWLN + gradient projection + reverse planning; general = CWLN alone (the paper's baseline); arm-angle-sqp = seed 002's arm-angle SQP (task.kind = 'sequential_reach', SRS arms).", choices=("seed", "general", "arm-angle-sqp")),
        "damping": _pos("Damping lambda of the least-norm solve (mm).", 0.1, "", 1000),
        "orientation_weight_mm": _pos("Length that weighs orientation error against position error: 1 rad counts as this many mm.", 200.0),
        "position_tol_mm": _pos("IK position tolerance.", 1e-4, " mm"),
        "orientation_tol_deg": _pos("IK orientation tolerance.", 1e-4, " deg"),
        "max_iterations": Key("int", 100, "IK iterations per point.", check=lambda x: 1 <= x <= 10_000, expect="an integer in 1..10000"),
        "track_scale_mm": _pos("Joint-space metric: 1 rad of a revolute joint weighs as much as this much track travel.", 500.0),
        "posture_gain": _nonneg("seed method only: per-point null-space pull towards mid-range (0 = off); keeps least-norm drift out of singular postures.", 0.001, 10),
        "clamp_buffer_deg": _pos("Width of the buffer inside each revolute limit where the clamping weight falls to 0.", 10.0),
        "clamp_buffer_mm": _pos("The same buffer for prismatic joints.", 50.0),
        "jump_threshold_deg": _pos("A revolute joint step above this between adjacent points is a jump.", 50.0),
        "jump_threshold_mm": _pos("A track step above this between adjacent points is a jump.", 100.0),
        "retract_mm": _pos("Lift of the tool along the surface normal (a Cartesian move of all joints) in a retract-reorient-return move inside a run.", 200.0),
        "chord_tol_mm": Key("float", 0.05, "Largest distance of the TCP from the straight line between two work poses when the controller moves the joints linearly between them; steps that bow further get intermediate poses (half of check.path_tol_mm by default).", check=lambda x: 0.001 <= x <= 10, expect="a number in 0.001..10 mm"),
        "smooth_runs": Key("bool", True, "Smooth each surface run whose planned joint path would need more than 85 % of a joint's acceleration or jerk limit at the commanded feed (a joint stopped short at its clamping buffer, the others taking over at once): a null-space least-squares fit keeps the tool on every pose and spreads the change over the row, so the row can run at the feed (docs/planner.md)."),
        "lift_mm": _pos("Reconfigure off the surface: a connector between runs whose joints change by more than the reconfigure thresholds lifts the tool this far along the surface normal, reconfigures there and comes back down. Default: 100 mm, room for a tool of up to ~60 mm radius plus margin; raise it for bigger tools.", 100.0, " mm"),
        "lift_steps": Key("int", 5, "Poses of each Cartesian lift and descent.", check=lambda x: 1 <= x <= 100, expect="an integer in 1..100"),
        "reconfigure_threshold_deg": _pos("A connector whose revolute joints change by more than this is a reconfiguration and is lifted off the surface.", 10.0, " deg"),
        "reconfigure_threshold_mm": _pos("The same for the track (mm).", 50.0, " mm"),
        "reverse_samples": Key("int", 50, "Random IK solutions tried by reverse planning.", check=lambda x: 1 <= x <= 100000, expect="an integer in 1..100000"),
        "reverse_best_of": Key("int", 5, "Reverse planning keeps the cheapest of up to this many successful candidates (reconfiguration time at the speed limits into the run, plus the run's own joint travel); 1 = the first that works.", check=lambda x: 1 <= x <= 1000, expect="an integer in 1..1000"),
        "seed": Key("int", 0, "Random seed for reverse planning and start-configuration search.", check=lambda x: 0 <= x < 2**63, expect="an integer >= 0"),
        "ik_seeds": Key("str", "random", "Where reverse planning, the start-configuration search and lost-pose restarts take their IK candidates: random = CWLN from random starts; analytic = the closed-form families (SRS arm-angle IK at a random arm angle and track value; 6R spherical wrist), each polished by one CWLN solve, then random starts; auto = analytic when the robot has closed-form families, else random (docs/seed-methods.md).", choices=("random", "auto", "analytic")),
    },
    "timing": {
        "method": Key("str", "quintic", "Interpolation between surface poses: quintic = the time law's own quintic Hermite pieces (a cubic spline through the poses, exact at constant feed); ruckig = jerk-limited ruckig state-to-state moves between the same states (docs/timing.md).", choices=("quintic", "ruckig")),
        "tcp_speed_mm_s": _pos("Commanded TCP feed on work zones (see feed and slow_scope).", 100.0, " mm/s", 10_000),
        "check_dt_ms": Key("float", 4.0, "Step at which the independent checker resamples the trajectory.", check=lambda x: 0.1 <= x <= 100, expect="a number in 0.1..100 ms"),
        "zones": Key("str", "flow", "Free zones between runs (self-motion, approach, depart): flow = one continuous jerk-limited motion along a spline through the free poses, at rest only at run ends, reconfiguration jumps, retract steps and corners of inserted free moves; stop = a rest-to-rest move per free pose (docs/timing.md).", choices=("flow", "stop")),
        "feed": Key("str", "constant", "Feed on work: constant = each row's work at one feed (the commanded one, or the highest constant feed the limits allow, see slow_scope), speed changes in the leads; max = as fast as the limits allow up to the commanded feed, speed changes wherever needed (docs/timing.md).", choices=("constant", "max")),
        "slow_scope": Key("str", "row", "feed = 'constant': where a row cannot run at the commanded feed, row = the whole row runs at the highest constant feed that fits; stretch = only the stretch that cannot, at its own highest constant feed (the speed changes in the work next to it).", choices=("row", "stretch")),
    },
    "check": {
        "dt_ms": Key("float", 4.0, "Step at which the independent motion check samples the program's joint-linear motion (docs/motion-check.md).", check=lambda x: 0.1 <= x <= 4.0, expect="a number in 0.1..4 ms"),
        "penetration_tol_mm": Key("float", 0.1, "Deepest the TCP or any checked body may go behind the part's surface. Point clouds add 3x the fit's RMS residual for scan noise.", check=lambda x: 0 <= x <= 10, expect="a number in 0..10 mm"),
        "clearance_mm": Key("float", 5.0, "Free clearance required of the tool and the wrist / forearm links off work (self-motion, approach, depart, retract).", check=lambda x: 0 <= x <= 1000, expect="a number in 0..1000 mm"),
        "path_tol_mm": Key("float", 0.1, "Largest distance of the TCP from the part's surface on work (the joint-linear bow between program points, measured at dt_ms). Point clouds add 3x the fit's RMS residual for scan noise.", check=lambda x: 0 < x <= 100, expect="a number in (0, 100] mm"),
        "tool_radius_mm": Key("float", 25.0, "Radius of the tool capsule (flange to TCP).", check=lambda x: 0 < x <= 1000, expect="a number in (0, 1000] mm"),
        "link_radius_mm": Key("float", 60.0, "Radius of the wrist, forearm and upper-arm capsules.", check=lambda x: 0 < x <= 1000, expect="a number in (0, 1000] mm"),
        "tool_contact_exempt_mm": Key("float", 100.0, "Length of the chain before the TCP left out of the capsule checks (the tool touches the part on work by design; the TCP itself is always checked). It reaches into the wrist when the tool is shorter.", check=lambda x: 0 <= x <= 2000, expect="a number in 0..2000 mm"),
    },
    "task": {
        "kind": Key("str", "raster", "What the job does: raster = the surface raster of the main seed; sequential_reach = seed 002's reaching task on a plane; cartesian = seed 001's line and arc moves (docs/seed-methods.md).", choices=("raster", "sequential_reach", "cartesian")),
        "allow_partial": Key("bool", False, "raster: when some poses are out of reach, plan and program the reachable stretches of the rows (each cut at its unreachable poses, with a lift between) and report the coverage; never the default (docs/placement.md).", ),
        "route": Key("str", "horizontal", "sequential_reach: S-shaped sweep along the grid rows (horizontal) or columns (vertical).", choices=("horizontal", "vertical")),
        "plane": Key("str", "fit", "sequential_reach: the target plane is the RANSAC plane fitted to the workpiece (fit), or plane_point_mm / plane_normal (job); the grid is projected onto it.", choices=("fit", "job")),
        "plane_point_mm": Key("vec3", [0.0, 600.0, 0.0], "sequential_reach, plane = 'job': a point of the target plane (world frame)."),
        "plane_normal": Key("vec3", [0.0, 1.0, 0.0], "sequential_reach, plane = 'job': the plane's normal (either sign; the tool z axis points away from the robot base)."),
        "grid_origin_mm": Key("vec3", [-350.0, 600.0, 250.0], "sequential_reach: first target (m = n = 0), world frame."),
        "grid_step_mm": _pos("sequential_reach: target spacing in both grid directions.", 100.0, " mm"),
        "grid_columns": Key("int", 8, "sequential_reach: targets per row (m = 0..columns-1, along the plane's horizontal).", check=lambda x: 1 <= x <= 1000, expect="an integer in 1..1000"),
        "grid_rows": Key("int", 8, "sequential_reach: rows (n = 0..rows-1, along tool_y_world).", check=lambda x: 1 <= x <= 1000, expect="an integer in 1..1000"),
        "start_mm": Key("vec3", [350.0, 600.0, 950.0], "sequential_reach: start point (world frame), projected onto the plane; the sweep begins at the grid corner nearest to it."),
        "tool_y_world": Key("vec3", [0.0, 0.0, 1.0], "sequential_reach: world direction the tool y axis follows (projected onto the plane)."),
        "hop_mm": Key("float", 20.0, "sequential_reach: between targets the tool lifts this far off the plane (along its normal), moves, and comes down, so no move grazes the part.", check=lambda x: 1 <= x <= 500, expect="a number in 1..500 mm"),
        "arm_angle0_deg": Key("float", 45.0, "arm-angle-sqp: the fixed arm angle and the SQP start (seed 002: pi/4)."),
        "sqp_max_iterations": Key("int", 200, "arm-angle-sqp: SLSQP iteration limit per family.", check=lambda x: 1 <= x <= 10_000, expect="an integer in 1..10000"),
        "track_mm": Key("float", 0.0, "arm-angle-sqp on seed8: the fixed track position."),
        "cart_start_mm": Key("vec3", [900.0, -200.0, 1000.0], "cartesian: start TCP position (world frame)."),
        "cart_start_rpy_deg": Key("vec3", [0.0, 180.0, 0.0], "cartesian: start TCP orientation (fixed-axis roll, pitch, yaw); kept along every move."),
        "line_down_mm": Key("float", 400.0, "cartesian: first line, this far along the tool z axis.", check=lambda x: abs(x) >= 1.0, expect="a length of at least 1 mm (either sign)"),
        "line_side_mm": Key("float", 400.0, "cartesian: second line, this far along world +y.", check=lambda x: abs(x) >= 1.0, expect="a length of at least 1 mm (either sign)"),
        "line_points": Key("int", 300, "cartesian: interpolation points of both lines together (seed 001: 300).", check=lambda x: 4 <= x <= 200_000, expect="an integer in 4..200000"),
        "arc_radius_mm": _pos("cartesian: radius of the arc after the lines (horizontal, centre on the -x side of its start).", 100.0, " mm"),
        "arc_angle_deg": Key("float", 360.0, "cartesian: angle the arc turns about world +z.", check=lambda x: x != 0, expect="a non-zero angle"),
        "arc_points": Key("int", 628, "cartesian: interpolation points of the arc (seed 001: 628).", check=lambda x: 2 <= x <= 200_000, expect="an integer in 2..200000"),
        "path_tol_mm": Key("float", 0.01, "cartesian: largest distance of the timed TCP from its line or arc, checked between points too; moves get more points until it holds.", check=lambda x: 1e-4 <= x <= 100, expect="a number in 0.0001..100 mm"),
    },
    "post": {
        "formats": Key("strs", ["rapid", "inform", "csv"], "Post-processor plugins to run (see `camtool posts`); at least one, each once.", check=lambda x: 0 < len(x) == len(set(x)), expect="a non-empty list of distinct format names"),
        "program_name": Key("str", "CAMTOOL", "Program / job name (sanitised per controller).", check=lambda x: bool(x.strip()), expect="a non-empty name"),
        "profiles": Key("table", {}, "Controller profile file per format, e.g. {rapid = 'my_irc5.toml'}; default: the shipped profile for the robot."),
        "path_tol_mm": _pos("Largest distance of the programs' interpolated TCP from the planned path on work (the program simulator checks it); moves are merged and corners blended within it.", 0.1, " mm"),
        "ori_tol_deg": _pos("Largest tool-orientation deviation of merged Cartesian moves (MoveL / MOVL).", 0.5, " deg"),
        "min_move_ms": _nonneg("Shortest program move: inserted samples of free moves closer than this are dropped (path poses are always kept).", 20.0, 10_000),
        "csv_angle_unit": Key("str", "deg", "Angle unit of CSV output.", choices=("deg", "rad")),
    },
}


class Section(dict):
    """A job section: a dict whose keys are also attributes."""

    __getattr__ = dict.__getitem__


@dataclass(frozen=True)
class Job:
    """A validated job: every key present (defaults filled), plus its file."""

    path: Path
    sections: dict[str, Section]

    def __getattr__(self, name: str) -> Section:
        try:
            return self.sections[name]
        except KeyError:
            raise AttributeError(name) from None

    @property
    def dir(self) -> Path:
        return self.path.parent

    def resolve(self, file: str) -> Path:
        """A path from the job file, relative to the job's folder."""
        p = Path(file)
        return p if p.is_absolute() else self.dir / p

    def as_dict(self) -> dict:
        return {name: dict(sec) for name, sec in self.sections.items()}


def _describe(value) -> str:
    return repr(value) if not isinstance(value, dict) else "a table"


def _coerce(key: Key, value, where: str):
    def fail(expect):
        raise BadInput(f"{where}: expected {expect}, found {_describe(value)}")

    def number(x):
        return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x)

    k = key.kind
    if k == "float":
        if not number(value):
            fail(key.expect or "a number")
        value = float(value)
    elif k == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            fail(key.expect or "an integer")
    elif k == "str":
        if not isinstance(value, str):
            fail("a string")
        if key.choices and value not in key.choices:
            fail("one of " + ", ".join(repr(c) for c in key.choices))
    elif k == "bool":
        if not isinstance(value, bool):
            fail("true or false")
    elif k == "vec3":
        if not (isinstance(value, (list, tuple)) and len(value) == 3 and all(number(x) for x in value)):
            fail("a list of 3 numbers")
        value = [float(x) for x in value]
    elif k == "floats":
        if not (isinstance(value, (list, tuple)) and all(number(x) for x in value)):
            fail("a list of numbers")
        value = [float(x) for x in value]
    elif k == "strs":
        if not (isinstance(value, list) and all(isinstance(x, str) for x in value)):
            fail("a list of strings")
    elif k == "table":
        if not isinstance(value, dict):
            fail("a table")
    elif k == "obstacles":
        from .collision.spec import parse_obstacles
        value = parse_obstacles(value, where)
    elif k == "pairs":
        from .collision.spec import parse_pairs
        value = parse_pairs(value, where)
    if key.check is not None and not key.check(value):
        fail(key.expect)
    name = where.rsplit(".", 1)[-1]
    values = value if isinstance(value, list) else [value] if k == "float" else []
    if name.endswith("_mm") and any(abs(x) > MAX_LENGTH_MM for x in values):
        fail(f"lengths within +-{MAX_LENGTH_MM:g} mm (1 km; a larger one is a typo or a unit slip)")
    if name.endswith("_deg") and k in ("float", "vec3", "floats") and any(abs(x) > MAX_ANGLE_DEG for x in values):
        fail(f"angles within +-{MAX_ANGLE_DEG:g} deg")
    return value


def parse_override(text: str) -> tuple[str, str, Any]:
    """Parse ``section.key=VALUE`` (VALUE as a TOML value, or a bare string)."""
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise BadInput(f"--set {text!r}: expected SECTION.KEY=VALUE, e.g. raster.step_over_mm=5")
    path, raw = text.split("=", 1)
    section, key = path.strip().split(".", 1)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw  # a bare word such as plane or ruckig
    return section, key, value


def validate(data: dict, source: str, overrides: list[str] = ()) -> dict[str, Section]:
    """Check a parsed job against SCHEMA, fill defaults, apply ``--set`` overrides."""
    data = {k: dict(v) if isinstance(v, dict) else v for k, v in data.items()}
    for text in overrides:
        section, key, value = parse_override(text)
        if section not in SCHEMA:
            raise BadInput(f"--set {section}.{key}: unknown section{_closest(section, SCHEMA)} (see docs/job-file.md)")
        if key not in SCHEMA[section]:
            raise BadInput(f"--set {section}.{key}: unknown key{_closest(key, SCHEMA[section])} (see docs/job-file.md)")
        data.setdefault(section, {})[key] = value
    sections = {}
    for name in data:
        if name not in SCHEMA:
            raise BadInput(f"{source}: {name}: unknown section{_closest(name, SCHEMA)} (expected one of "
                           f"{', '.join(SCHEMA)})")
        if not isinstance(data[name], dict):
            raise BadInput(f"{source}: {name}: expected a [{name}] table, found {_describe(data[name])}")
    for name, keys in SCHEMA.items():
        given = data.get(name, {})
        for k in given:
            if k not in keys:
                raise BadInput(f"{source}: {name}.{k}: unknown key{_closest(k, keys)} (expected one of "
                               f"{', '.join(keys)})")
        sec = Section()
        for k, key in keys.items():
            value = given.get(k, key.default)
            sec[k] = _coerce(key, value, f"{source}: {name}.{k}") if k in given else _copy(key.default)
        sections[name] = sec
    return sections


def _copy(v):
    return list(v) if isinstance(v, list) else dict(v) if isinstance(v, dict) else v


def load_job(path: str | Path, overrides: list[str] = ()) -> Job:
    """Read and validate a job file; raises BadInput naming the file and key."""
    p = Path(path)
    if p.is_dir():
        raise BadInput(f"{p}: is a directory, expected a job file (.toml)")
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise BadInput(f"{p}: job file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise BadInput(f"{p}: cannot read job file ({exc})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise BadInput(f"{p}: TOML syntax error: {exc}") from None
    job = Job(p, validate(data, str(p), overrides))
    _check_cross(job)
    return job


def _check_cross(job: Job) -> None:
    """Checks that involve more than one key or the file system."""
    from .robots import BUILTIN_ROBOTS

    name = job.robot.name
    if name not in BUILTIN_ROBOTS:
        if not name.lower().endswith((".toml", ".urdf")):
            raise BadInput(f"{job.path}: robot.name: expected a built-in robot ({', '.join(BUILTIN_ROBOTS)}) "
                           f"or a .toml/.urdf file, found {name!r}")
        if not job.resolve(name).is_file():
            raise BadInput(f"{job.path}: robot.name: robot file {job.resolve(name)} not found")
    for fmt in job.post.profiles:
        if fmt not in job.post.formats:
            raise BadInput(f"{job.path}: post.profiles: {fmt!r} is not one of post.formats "
                           f"({', '.join(job.post.formats)}){_closest(fmt, job.post.formats)}")
    if not job.workpiece.file:
        raise BadInput(f"{job.path}: workpiece.file: expected the workpiece file name, found nothing")
    for i, ob in enumerate(job.cell.obstacles):
        if "mesh" in ob and not job.resolve(ob["mesh"]).is_file():
            raise BadInput(f"{job.path}: cell.obstacles[{i}] ({ob['name']}).mesh: file {job.resolve(ob['mesh'])} not found")
    if job.tool.mesh and not job.resolve(job.tool.mesh).is_file():
        raise BadInput(f"{job.path}: tool.mesh: file {job.resolve(job.tool.mesh)} not found")


def schema_markdown() -> str:
    """The job-file reference as Markdown (docs/job-file.md)."""
    lines = ["# Job-file reference", "",
             "A job is a TOML file. One key is required: `workpiece.file` (except that a",
             "`task.kind = \"sequential_reach\"` job with `task.plane = \"job\"` or a `cartesian` job does not",
             "read it, it must still name a file). Every other key is optional and has the default shown;",
             "relative file names are taken from the job file's folder. Every count and step has an upper",
             f"bound, lengths (`_mm`) lie within +-{MAX_LENGTH_MM:g} mm and angles (`_deg`) within",
             f"+-{MAX_ANGLE_DEG:g} deg; an unknown key is refused with the closest known one named.",
             "Generated from `camtool/job.py` by `python -m camtool.job --markdown`.", ""]
    for name, keys in SCHEMA.items():
        lines += [f"## [{name}]", "", "| key | type | default | meaning |", "|---|---|---|---|"]
        for k, key in keys.items():
            extra = f" One of: {', '.join(key.choices)}." if key.choices else ""
            default = repr(key.default).replace("'", '"')
            lines.append(f"| `{k}` | {key.kind} | `{default}` | {key.doc}{extra} |")
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    import sys

    if "--markdown" in sys.argv:
        sys.stdout.write(schema_markdown())
