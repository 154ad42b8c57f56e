"""An example third-party post-processor: a Universal Robots URScript program of joint moves.

Written only against camtool's documented plugin base (``camtool.program.plugin``,
docs/plugins.md): it derives from ``PostProcessor``, declares its name, extension and
options, writes one ``movej`` per waypoint with the planned duration (``t=``) and reads its
own file back. It has no ``check`` of its own, so camtool reads it back and checks the
joint values and durations against the robot's limits; it has no ``read_program``, so it
is not simulated. Install it with ``pip install examples/urscript_post``.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from camtool.errors import BadInput
from camtool.program.plugin import PostProcessor
from camtool.program.text import sanitise_name

MOVEJ_RE = re.compile(r"^  movej\(\[(?P<q>[^\]]*)\], t=(?P<t>[0-9.eE+-]+), r=0\)$")


class UrScriptPost(PostProcessor):
    """URScript ``movej`` program (see module doc)."""

    name = "urscript"
    extension = ".script"
    requires_profile = False
    options_schema = {"decimals": (int, 6, "Decimals of joint values (rad).")}

    def validate_profile(self, profile, robot) -> None:
        if robot.dof != 6 or any(robot.prismatic):
            raise BadInput(f"urscript: robot {robot.name} is not a six-axis revolute arm")
        if not 3 <= profile.options.get("decimals", 6) <= 9:
            raise BadInput(f"{profile.source}: options.decimals: expected 3..9")

    def write(self, trajectory, robot, profile, outdir, process):
        self.validate_profile(profile, robot)
        d = profile.options.get("decimals", 6)
        name, _ = sanitise_name(profile.program_name, max_len=32, what="URScript function name")
        t = np.asarray(trajectory.t_s, float)
        dt = np.r_[0.0, np.diff(t)]
        lines = [f"def {name}():"]
        for k, q in enumerate(np.asarray(trajectory.q, float)):
            lines.append(f"  movej([{', '.join(f'{v:.{d}f}' for v in q)}], t={max(dt[k], 0.0):.4f}, r=0)")
        lines.append("end")
        path = Path(outdir) / f"{name}.script"
        path.write_bytes(("\n".join(lines) + "\n").encode("ascii"))
        return [path]

    def read(self, path, robot, profile):
        text = Path(path).read_bytes().decode("ascii", "replace")
        rows = [m for m in map(MOVEJ_RE.match, text.splitlines()) if m]
        if not text.rstrip().endswith("end") or not rows:
            raise BadInput(f"{path}: not a complete camtool URScript program")
        q = np.array([[float(v) for v in m.group("q").split(",")] for m in rows])
        dur = np.array([float(m.group("t")) for m in rows])
        dur[0] = np.nan  # the first move comes from wherever the robot is
        return dur, q
