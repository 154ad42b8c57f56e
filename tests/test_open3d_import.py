"""camtool.part.open3d_import: open3d without plotly and dash, its viewer still there when asked for."""
import subprocess
import sys

import numpy as np

SCRIPT = """
import sys
from camtool.part.open3d_import import import_open3d
o3d = import_open3d()
scene = o3d.t.geometry.RaycastingScene()
scene.add_triangles(o3d.core.Tensor([[0, 0, 0], [1, 0, 0], [0, 1, 0]], o3d.core.float32),
                    o3d.core.Tensor([[0, 1, 2]], o3d.core.uint32))
hit = scene.cast_rays(o3d.core.Tensor([[0.2, 0.2, 1, 0, 0, -1]], o3d.core.float32))["t_hit"].numpy()
print(float(hit[0]), "dash" in sys.modules, "plotly" in sys.modules)
fig = o3d.visualization.get_plotly_fig([o3d.geometry.TriangleMesh.create_box()])
print(type(fig).__module__.split(".")[0], "dash" in sys.modules)
"""


def test_open3d_works_without_dash_until_its_viewer_is_used():
    """A mesh query needs no plotly or dash (the import's cost); the viewer loads them when it is called."""
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True).stdout.split()
    assert np.isclose(float(out[0]), 1.0) and out[1:3] == ["False", "False"]   # the ray's hit 1 below its origin
    assert out[3:] == ["plotly", "True"]
