"""Job files (TOML): schema, defaults and validation with precise messages.

A job has the sections ``workpiece``, ``fit``, ``raster``, ``robot``, ``cell``,
``tool``, ``planner``, ``timing``, ``check``, ``task``, ``process`` and ``post``. Every key has a default
(``SCHEMA``); docs/job-file.md is generated from it (``python -m
camtool.job --markdown``) and a test keeps the two in step.

Errors name the file, the key path, what was expected and what was found::

    job.toml: raster.step_over_mm: expected a number > 0, found -5
"""
from __future__ import annotations

import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from .errors import BadInput, closest


MAX_LENGTH_MM = 1e6   # no length of a robot cell is longer than 1 km
MAX_ANGLE_DEG = 3600.0  # no angle of a job is more than ten turns


_closest = closest  # moved to errors.py so collision/spec.py can use it without importing job


@dataclass(frozen=True)
class Key:
    """One job-file key: its kind, default, doc line and optional check."""

    kind: str  # float | int | str | bool | vec3 | floats | strs | table
    default: Any
    doc: str
    choices: tuple = ()
    check: Callable[[Any], bool] | None = None
    expect: str = ""  # wording of the check for error messages
    auto: bool = False  # the string "auto" is accepted too (a value camtool chooses)


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
        "scan": Key("str", "auto", "Whether a mesh is a scan, whose TCP contact the motion check judges within the scan's noise band (a point cloud always is): auto = when its vertices are rough (docs/freeform.md, \"Scanned meshes\"; a coarse CAD mesh's facets read as rough too); yes; no = a CAD mesh, checked strictly, its free-form faces' normals its own triangles' averaged over the tool's footprint.", choices=("auto", "yes", "no")),
    },
    "fit": {
        "model": Key("str", "auto", "Surface model; auto takes the one with most inliers (a huge sphere counts as a plane; a cylinder needs 5 % more inliers than the plane or sphere); freeform takes the whole workpiece as one free-form face, rows measured on the surface (docs/freeform.md).", choices=("auto", "plane", "sphere", "cylinder", "freeform")),
        "threshold_mm": _pos("RANSAC inlier distance.", 0.5, " mm"),
        "iterations": Key("int", 1000, "RANSAC hypotheses per model.", check=lambda x: 1 <= x <= 100_000, expect="an integer in 1..100000"),
        "min_inlier_ratio": Key("float", 0.2, "Smallest inlier share a model must reach.", check=lambda x: 0 < x <= 1, expect="a number in (0, 1]"),
        "seed": Key("int", 0, "Random seed: the same seed gives the same fit.", check=lambda x: 0 <= x < 2**63, expect="an integer >= 0"),
        "boundary_cell_mm": _pos("Cell size of the occupancy image used to find the boundary.", 2.0, " mm"),
        "close_gaps_mm": _nonneg("Gaps in the material up to this width are closed before contours are taken.", 6.0),
        "simplify_mm": _nonneg("Boundary polygons are simplified to this tolerance.", 0.5),
        "smoothing_mm": _nonneg("Free-form faces of a scan: the Gaussian sigma over which the points are smoothed into the surface (noise filtering); 0 = 2.5 point spacings, at least 2 mm (docs/freeform.md). Meshes are not smoothed.", 0.0, 100),
    },
    "raster": {
        "step_over_mm": Key("float", 10.0, "Distance between rows, measured on the surface (geodesic on a sphere); \"auto\" = the largest step-over whose predicted process map meets process.uniformity_target for the [process] footprint (docs/process.md).", check=lambda x: 0.1 <= x <= 10_000, expect="a number in 0.1..10000 mm", auto=True),
        "pitch_mm": Key("float", 5.0, "Spacing of points along a row, measured on the surface.", check=lambda x: 0.1 <= x <= 10_000, expect="a number in 0.1..10000 mm"),
        "angle_deg": Key("float", 0.0, "Row direction in the (u, v) domain, from the u axis.", check=lambda x: -360 <= x <= 360, expect="an angle within -360..360 deg"),
        "lead_mm": _nonneg("Lead-in / lead-out length beyond the boundary at each segment end (the shortest; see lead_auto).", 20.0),
        "lead_auto": Key("bool", True, "Lengthen the leads of every row to what the ramps to and from the feed need, so that the tool is at the feed at the first work point and until the last: on the planning kernel's plan, the length each run's ramps need is computed from the joint speed, acceleration and jerk limits, the feed and the planned joint path; when it is longer than lead_mm, the path is rastered again with that lead (5 % longer, rounded up to whole mm, at most lead_max_mm) and planned again, and the whole plan is made once with the lead chosen (docs/timing.md)."),
        "lead_max_mm": _pos("Longest lead that lead_auto may choose.", 100.0, " mm", 10_000),
        "clearance_mm": _nonneg("Lift of lead and transition points along the surface normal (the leads rise to it as the cube of the distance from the work, leaving the surface without a kink).", 0.0),
        "self_motion_lift_mm": _nonneg("The self-motion zone between rows runs at least this far off the surface (a sine arc along the normal), so the transition never cuts into the part: on a convex part a chord between two surface points dips below the surface.", 5.0),
        "max_poses": Key("int", 1_000_000, "The most poses a raster may have: a larger one is refused before any work (a run plans, times and checks every pose, minutes per million; at most 5000000, the memory cap).", check=lambda x: 1000 <= x <= 5_000_000, expect="an integer in 1000..5000000"),
        "transition_points": Key("int", 5, "Poses in each self-motion zone between segments.", check=lambda x: 2 <= x <= 1000, expect="an integer in 2..1000"),
        "tool_x": Key("str", "fixed", "Tool x axis: a fixed world direction, or the travel direction.", choices=("fixed", "travel")),
        "tool_x_world": Key("vec3", [0.0, 0.0, 1.0], "World direction the tool x axis follows when tool_x = 'fixed'."),
        "lead_deg": _angle89("Lead angle: tilt of the tool about its y axis, in the travel direction."),
        "tilt_deg": _angle89("Side-tilt angle: tilt of the tool about the travel direction."),
        "free_spin": Key("bool", False, "Rotation about tool z is free (symmetric tools); the planner may use it as redundancy."),
        "edge_margin": Key("float", 0.25, "The first and last rows stay at least this share of step_over_mm inside the face's edges: where rows centred step_over_mm apart would come nearer an edge (a face a little over whole steps wide, a scan's outline weaving by a point spacing), all rows are drawn closer together, never farther apart than step_over_mm. 0 = rows exactly step_over_mm apart, centred, the edges up to half a step from the first and last rows (the seed paper's raster; docs/raster.md).", check=lambda x: 0 <= x <= 0.5, expect="a share of the step-over in 0..0.5"),
        "contour": Key("str", "auto", "A contour pass after the rows: runs along every edge of the face, half a step-over inside it (at most; the edge stays within the coverage radius), split at corners. \"auto\" adds it where the rows alone cover less than 99.5 % of the face (a ring's curved rim, a strip a little wider than whole steps, a scan's weaving edge); \"on\" always, \"off\" never (docs/raster.md).", choices=("auto", "on", "off")),
        "lead_path": Key("str", "surface", "Where the leads run past the work: \"surface\" on the face's own surface continued (lifted by clearance_mm); \"tangent\" lifted off it too, as the cube of the distance from the work (no jump in curvature at the first and last work point), just enough to stay at or above the row's tangent plane at the work's end, wherever the face curves away from it (a convex face curved along the row: a sphere, a cylinder's rows around it; elsewhere the two are one). For a face that a neighbour continues tangentially (a dome on a cylinder of its radius), where the surface continued runs into the neighbour (docs/raster.md).", choices=("surface", "tangent")),
        "cylinder_rows": Key("str", "around", "On a cylinder face: rows run around the axis (circles, angle_deg = 0) or along it (lines); angle_deg turns them further (docs/raster.md).", choices=("around", "along")),
        "axis_tilt_max_deg": _nonneg("Free-form faces: where the tool or the robot's wrist (the motion check's capsules rigid with the TCP) would be inside the part at a pose on the surface (a pocket's wall, a bulge beside the face), the tool axis is tilted about the TCP (which stays on the surface) away from it, by the least angle that clears it by 1 mm, blended over the neighbouring poses; at most this tilt, else the run is refused naming the pose, the body and the tilt it would need; 0 = never tilted (docs/freeform.md, \"Tool axis tilted clear of the part\").", 30.0, 60),
        "axis_tilt_turn_deg": _pos("The most the tilt of axis_tilt_max_deg changes between neighbouring poses (its blend is a raised cosine of at most this slope).", 4.0, " deg", 10),
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
        "penetration_tol_mm": Key("float", 0.1, "Deepest the TCP or any checked body may go behind the part's surface. Point clouds add 3x the fit's RMS residual for scan noise; a scanned (rough) mesh's TCP on the part adds its noise band (docs/freeform.md).", check=lambda x: 0 <= x <= 10, expect="a number in 0..10 mm"),
        "clearance_mm": Key("float", 5.0, "Free clearance required of the tool and the wrist / forearm links off work (self-motion, approach, depart, retract).", check=lambda x: 0 <= x <= 1000, expect="a number in 0..1000 mm"),
        "path_tol_mm": Key("float", 0.1, "Largest distance of the TCP from the part's surface on work (the joint-linear bow between program points, measured at dt_ms). Point clouds add 3x the fit's RMS residual for scan noise; a scanned (rough) mesh's TCP on the part adds its noise band (docs/freeform.md).", check=lambda x: 0 < x <= 100, expect="a number in (0, 100] mm"),
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
    "process": {
        "kind": Key("str", "none", "What the tool does to the part, mapped over the worked surface (process_map.npz, report.json process_map; docs/process.md): polish and grind = removal depth by Preston's law, paint = film thickness, inspect = coverage count; none = no map.", choices=("none", "polish", "grind", "paint", "inspect")),
        "diameter_mm": _nonneg("Tool footprint diameter on the surface; 0 = the tool's size, 2 x check.tool_radius_mm.", 0.0),
        "profile": Key("str", "flat", "Radial shape of the footprint's pressure (polish, grind) or deposition (paint): flat, parabolic (1 - r^2/a^2), gaussian (sigma = gaussian_sigma_mm, cut at the diameter) or table (profile_radius_mm / profile_value, a measured radial table, linear between entries, 0 beyond the last).", choices=("flat", "parabolic", "gaussian", "table")),
        "gaussian_sigma_mm": _nonneg("profile = gaussian: standard deviation; 0 = diameter / 6.", 0.0),
        "profile_radius_mm": Key("floats", [], "profile = table: radii of the measured profile, increasing from 0.", check=lambda x: all(b > a for a, b in zip(x, x[1:])) and all(r >= 0 for r in x), expect="increasing radii >= 0"),
        "profile_value": Key("floats", [], "profile = table: relative pressure or deposition at each radius (any scale, >= 0; normalised so the footprint carries force_n or deposition_mm3_s).", check=lambda x: all(v >= 0 for v in x), expect="values >= 0"),
        "force_n": _pos("polish, grind: normal force of the tool on the part (spread over the footprint by the profile).", 15.0, " N", 100_000),
        "preston_coefficient_per_pa": _pos("polish, grind: Preston coefficient k_p in depth rate = k_p * pressure * relative speed (1/Pa = m^2/N); default: mr-sim's orbital-sander example.", 1.362e-9, " 1/Pa", 1.0),
        "relative_speed_m_s": _nonneg("polish, grind: speed of the abrasive over the part (belt, disc or orbit speed); 0 = the tool's own traverse speed (TCP speed).", 0.0, 1000),
        "deposition_mm3_s": _pos("paint: film volume the gun lays down per second (solids), spread over the footprint by the profile.", 1500.0, " mm^3/s", 1e9),
        "contact_tol_mm": _pos("The tool acts where its TCP is within this distance of the surface (along the normal): contact for polish and grind, the stand-off window for paint and inspect. Leads and transitions within it count.", 0.5, " mm", 1000),
        "grid_mm": _nonneg("Cell size of the map on the surface; 0 = diameter / 25.", 0.0, 1000),
        "uniformity_target": Key("float", 0.95, "Share of the worked area that raster.step_over_mm = \"auto\" must bring within uniformity_band_pct of the mean.", check=lambda x: 0 < x <= 1, expect="a number in (0, 1]"),
        "uniformity_band_pct": _pos("Band round the mean for uniformity_target.", 5.0, " %", 100),
        "target_removal_file": Key("str", "", "A target removal map (.npz with u, v and values_um on the surface's (u, v) grid, or the process_map.npz of a run): the feed along the rows is modulated (dwell time) so the map meets it, within the joint limits (docs/process.md); empty = constant feed."),
        "dwell_iterations": Key("int", 12, "target_removal_file: iterations of the dwell-time solve.", check=lambda x: 1 <= x <= 200, expect="an integer in 1..200"),
        "feed_factor_min": Key("float", 0.25, "target_removal_file: lowest feed, as a share of timing.tcp_speed_mm_s (the longest dwell).", check=lambda x: 0.01 <= x <= 1, expect="a number in 0.01..1"),
    },
    "faces": {
        "select": Key("select", "single", "Which faces of the workpiece the job works: single = the one surface [fit] finds (as before faces existed); all; a list of face indices as `camtool faces JOB` prints them (largest first); a model name (plane, sphere, cylinder, freeform); {largest = N}; or {nearest_mm = [x, y, z]} (world frame). Any other choice splits the workpiece into faces (docs/faces.md); several faces are worked in one program."),
        "normal_tol_deg": Key("float", 10.0, "A point belongs to a face only when its normal is within this angle of the face's normal there.", check=lambda x: 0.5 <= x <= 45, expect="an angle in 0.5..45 deg"),
        "min_area_mm2": _nonneg("Faces smaller than this are dropped or merged (small_faces).", 100.0),
        "small_faces": Key("str", "drop", "What becomes of a face smaller than min_area_mm2: drop it, or merge its points into the neighbouring face they fit (within 3x fit.threshold_mm, normals agreeing).", choices=("drop", "merge")),
        "max_faces": Key("int", 32, "Most faces the segmentation looks for.", check=lambda x: 1 <= x <= 256, expect="an integer in 1..256"),
        "sharp_edge_deg": Key("float", 30.0, "Smooth regions of the part are split where the surface turns by more than this dihedral angle across an edge (a mesh's crease between two triangles, or within 3 mm; on a scan between neighbouring points); a smooth region the plane, sphere and cylinder faces hold only in fragments is one free-form face (docs/faces.md).", check=lambda x: 5 <= x <= 90, expect="an angle in 5..90 deg"),
        "raster": Key("table", {}, "Raster keys per face index, e.g. {\"2\" = {step_over_mm = 5, cylinder_rows = \"along\"}}; needs select = [indices] or {largest = N}."),
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
        """The sections as plain dicts, keys left unset (None, e.g. cell.floor_z_mm) omitted:
        TOML has no null, and an omitted key reads back as the same default."""
        return {name: {k: _drop_none(v) for k, v in sec.items() if v is not None}
                for name, sec in self.sections.items()}


def _drop_none(value):
    if isinstance(value, dict):
        return {k: _drop_none(v) for k, v in value.items() if v is not None}
    if isinstance(value, list):
        return [_drop_none(v) for v in value]
    return value


def _describe(value) -> str:
    if isinstance(value, dict):
        return "a table"
    text = repr(value)  # a bounded quote: a 5 MB value is not echoed whole
    return text if len(text) <= 80 else f"{text[:80]}... ({len(text)} characters)"


MIN_GRID_MM = 0.05  # process.grid_mm: finer is no measurement and a map of billions of cells
MAX_STRING_CHARS = 4096  # any string of a job (names, file names): more is a mistake or an attack
# program names whose file would be one of camtool's own (points.csv, report.json, plots/, stage files)
OWN_FILE_STEMS = {"points": "points.csv", "report": "report.json and report.html", "plots": "the plots/ folder",
                  "summary": "summary.json", "path": "path.npz", "joint_path": "joint_path.npz",
                  "trajectory": "trajectory.npz", "surface": "surface.json"}


def _coerce(key: Key, value, where: str):
    def fail(expect):
        raise BadInput(f"{where}: expected {expect}, found {_describe(value)}")

    def number(x):
        return not isinstance(x, bool) and isinstance(x, (int, float)) and math.isfinite(x)

    k = key.kind
    if key.auto and value == "auto":
        return value
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
        if len(value) > MAX_STRING_CHARS:
            raise BadInput(f"{where}: a string of {len(value)} characters; at most {MAX_STRING_CHARS} are accepted")
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
        if len(value) > MAX_STRING_CHARS or any(len(x) > MAX_STRING_CHARS for x in value):
            raise BadInput(f"{where}: a list too long or with a string over {MAX_STRING_CHARS} characters")
    elif k == "table":
        if not isinstance(value, dict):
            fail("a table")
    elif k == "obstacles":
        from .collision.spec import parse_obstacles
        value = parse_obstacles(value, where)
    elif k == "pairs":
        from .collision.spec import parse_pairs
        value = parse_pairs(value, where)
    elif k == "select":
        value = _faces_select(value, fail)
    if key.check is not None and not key.check(value):
        fail(key.expect)
    name = where.rsplit(".", 1)[-1]
    values = value if isinstance(value, list) else [value] if k == "float" else []
    if name.endswith("_mm") and any(abs(x) > MAX_LENGTH_MM for x in values):
        fail(f"lengths within +-{MAX_LENGTH_MM:g} mm (1 km; a larger one is a typo or a unit slip)")
    if name.endswith("_deg") and k in ("float", "vec3", "floats") and any(abs(x) > MAX_ANGLE_DEG for x in values):
        fail(f"angles within +-{MAX_ANGLE_DEG:g} deg")
    return value


FACE_MODELS = ("plane", "sphere", "cylinder", "freeform")


def _faces_select(value, fail):
    """faces.select: 'single', 'all', a model name, [indices], {largest = N} or {nearest_mm = [x, y, z]}."""
    expect = ("'single', 'all', 'plane', 'sphere', 'cylinder', 'freeform', a list of face indices, {largest = N} "
              "or {nearest_mm = [x, y, z]}")
    if isinstance(value, str):
        if value not in ("single", "all", *FACE_MODELS):
            fail(expect)
        return value
    if isinstance(value, list):
        if not value or not all(isinstance(i, int) and not isinstance(i, bool) and 0 <= i < 10_000 for i in value) \
                or len(set(value)) != len(value):
            fail("a non-empty list of distinct face indices (integers >= 0)")
        return list(value)
    if isinstance(value, dict) and len(value) == 1:
        (key, v), = value.items()
        if key == "largest" and isinstance(v, int) and not isinstance(v, bool) and 1 <= v <= 10_000:
            return {"largest": v}
        if key == "nearest_mm" and isinstance(v, list) and len(v) == 3 and all(
                isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and abs(x) <= MAX_LENGTH_MM
                for x in v):
            return {"nearest_mm": [float(x) for x in v]}
    fail(expect)


def parse_override(text: str) -> tuple[str, str, Any]:
    """Parse ``section.key=VALUE`` (VALUE as a TOML value, or a bare string)."""
    if "=" not in text or "." not in text.split("=", 1)[0]:
        raise BadInput(f"--set {text!r}: expected SECTION.KEY=VALUE, e.g. raster.step_over_mm=5")
    path, raw = text.split("=", 1)
    section, key = path.strip().split(".", 1)
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except (tomllib.TOMLDecodeError, RecursionError):
        value = raw  # a bare word such as plane or ruckig
    except ValueError:  # an integer past Python's 4300-digit conversion limit
        raise BadInput(f"--set {section.strip()}.{key.strip()}: a number with too many digits") from None
    return section, key, value


def _check_values(value, where: str, depth: int = 0) -> None:
    """BadInput for a value no key of a job takes: a NUL byte in any string (no file name holds one), an
    integer no float holds (5000 digits), nesting deeper than a job's tables."""
    if depth > 16:
        raise BadInput(f"{where}: nested more than 16 levels; a job's values are flat")
    if isinstance(value, str):
        if "\0" in value:
            raise BadInput(f"{where}: holds a NUL byte; no name or file name has one")
    elif isinstance(value, int) and not isinstance(value, bool):
        if value.bit_length() > 1000:
            raise BadInput(f"{where}: an integer of more than 300 digits; give a real value")
    elif isinstance(value, dict):
        for k, v in value.items():
            _check_values(k, where, depth + 1)
            named = depth < 2 and "\0" not in str(k) and len(str(k)) < 100
            _check_values(v, (f"{where}: {k}" if depth == 0 else f"{where}.{k}") if named else where, depth + 1)
    elif isinstance(value, list):
        for v in value:
            _check_values(v, where, depth + 1)


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
    _check_values(data, source)
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
    from .safe_io import load_toml, read_input_text

    p = Path(path)
    if p.is_dir():
        raise BadInput(f"{p}: is a directory, expected a job file (.toml)")
    # one checked read (regular file, size cap, never blocks on a FIFO); deep nesting is one line too
    data = load_toml(p, "job", read_input_text(p, "job"))
    job = Job(p, validate(data, str(p), overrides))
    _check_cross(job)
    return job


def job_for_part(path: str | Path, units: str = "mm", overrides: list[str] = ()) -> Job:
    """A job of defaults around a bare mesh or point cloud (``camtool faces PART``): the part in its own frame,
    in ``units``; ``overrides`` as on a job file (e.g. ``faces.sharp_edge_deg=20``)."""
    p = Path(path)
    data = {"workpiece": {"file": str(p.resolve()), "units": units}}
    job = Job(p, validate(data, str(p), overrides))
    _check_cross(job)
    return job


def _check_cross(job: Job) -> None:
    """Checks that involve more than one key or the file system."""
    from .robots import BUILTIN_ROBOTS

    grid = job.process.grid_mm
    if job.process.kind != "none" and 0 < grid < MIN_GRID_MM:  # before any work: the map's size is bounded later
        raise BadInput(f"{job.path}: process.grid_mm = {grid:g}: a process map cell is at least {MIN_GRID_MM:g} mm "
                       "(0 = diameter / 25)")
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
    stem = re.sub(r"[^a-z0-9_]", "_", job.post.program_name.strip().lower())
    if stem in OWN_FILE_STEMS:
        raise BadInput(f"{job.path}: post.program_name = {job.post.program_name!r}: its program would clash with "
                       f"camtool's own {OWN_FILE_STEMS[stem]}; choose another name")
    _check_face_raster(job)
    if not job.workpiece.file:
        raise BadInput(f"{job.path}: workpiece.file: expected the workpiece file name, found nothing")
    for i, ob in enumerate(job.cell.obstacles):
        if "mesh" in ob and not job.resolve(ob["mesh"]).is_file():
            raise BadInput(f"{job.path}: cell.obstacles[{i}] ({ob['name']}).mesh: file {job.resolve(ob['mesh'])} not found")
    if job.tool.mesh and not job.resolve(job.tool.mesh).is_file():
        raise BadInput(f"{job.path}: tool.mesh: file {job.resolve(job.tool.mesh)} not found")


def _check_face_raster(job: Job) -> None:
    """faces.raster: keys are face indices the selection names, values valid [raster] keys."""
    table = job.faces.raster
    if not table:
        return
    sel = job.faces.select
    static = sel if isinstance(sel, list) else list(range(sel["largest"])) if isinstance(sel, dict) and \
        "largest" in sel else None
    if static is None:
        raise BadInput(f"{job.path}: faces.raster: per-face raster keys need faces.select = [indices] or "
                       f"{{largest = N}} (the faces are then known by index), found select = {sel!r}")
    for index, keys in table.items():
        if not (isinstance(index, str) and index.isdigit() and int(index) in static):
            raise BadInput(f"{job.path}: faces.raster: {index!r} is not one of the selected face indices "
                           f"{static}")
        if not isinstance(keys, dict):
            raise BadInput(f"{job.path}: faces.raster.{index}: expected a table of [raster] keys")
        checked = validate({"raster": keys}, f"{job.path}: faces.raster.{index}")["raster"]
        if static == [int(index)]:  # the job's one face: its keys are the job's raster keys
            job.sections["raster"].update({k: checked[k] for k in keys})


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
