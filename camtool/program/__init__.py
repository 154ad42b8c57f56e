"""The controller-neutral program model: what every post-processor shares.

- ``plan``: the move list of a program (``MovePlan``: targets, kinds, times, blend levels,
  rows) made from a timed trajectory, and its splitting into parts and rounding of times;
  ``kinematics``: the batch TCP poses and Jacobians the steps measure with.
- ``moves``: a program read back (``ProgramMoves``), in the form every format shares;
  ``targets`` / ``durations``: the generic reading of it (joint values of Cartesian
  targets, each move's duration), used by every reader and by the simulator.
- ``convention``: the two points where the model meets a controller's conventions
  (joint values <-> axis values, TCP pose <-> stated target).
- ``plugin`` (the abstract ``PostProcessor`` base), ``registry`` (built-ins in code plus
  entry points), ``process`` (``ProcessInfo``), ``profiles`` (a profile for a plugin),
  ``check`` / ``check_program`` (what every check shares; a file by path), ``text``
  (identifiers), ``arcs`` (circle geometry).

See docs/architecture.md and docs/plugins.md.
"""
