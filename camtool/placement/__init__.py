"""Workpiece placement: where to put the part so that the robot reaches all of it with margin.

Modules (import them directly; this package file imports nothing, so that the
low-level ones can be used from ``camtool.run.stages`` and the tasks without an
import cycle):

- ``kinematics``: the robot's closed-form IK families, batched over many poses
  (SRS arm-angle IK incl. seed8's arm behind its track; 6R spherical wrist),
  the wrist-centre reach bound and a batched TCP Jacobian.
- ``margins``: ``reach_margins(path, joint_path, robot)``, the margins of a
  planned run (joint limits, reach, manipulability) for report.json.
- ``screen``: the fast reachability screen of one placement and its cost.
- ``shift``: ``nearest_feasible_shift(job, settings, robot, path, search)``, the smallest
  move of the workpiece that the screen finds reachable (for failed runs; ``ShiftSearch``: how far and how hard).
- ``partial``: ``reachable_stretches`` / ``partial_path``, the reachable parts
  of a path (for ``--allow-partial``).
- ``search``: ``camtool place``: raster screen over the user's bounds, local
  refinement, full planning of the best few (docs/placement.md).
- ``plots``: the feasible-region PNG.
"""
