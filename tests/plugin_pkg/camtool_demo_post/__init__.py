"""A minimal third-party post-processor: one line per waypoint, ``t q1 q2 ...`` (rad / mm)."""
from pathlib import Path

import numpy as np

from camtool.program.plugin import PostProcessor


class DemoPost(PostProcessor):
    name = "demo"
    extension = ".txt"
    requires_profile = False
    options_schema = {"separator": (str, " ", "Separator between values.")}

    def write(self, trajectory, robot, profile, outdir, process):
        sep = profile.options.get("separator", " ")
        rows = [sep.join(repr(float(v)) for v in (t, *q)) for t, q in zip(trajectory.t_s, trajectory.q)]
        path = Path(outdir) / f"{profile.program_name}.txt"
        path.write_text("\n".join(rows) + "\n")
        return [path]

    def read(self, path, robot, profile):
        data = np.loadtxt(path, ndmin=2)
        return np.concatenate([[np.nan], np.diff(data[:, 0])]), data[:, 1:]
