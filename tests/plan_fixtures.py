"""Small hand-built paths for planner tests (independent of the raster stage)."""
import numpy as np

from camtool.path.toolpath import ZONE_CODE, Path


def tool_pose(p, n_out, x_hint=(0.0, 0.0, 1.0)):
    """TCP pose at p with tool z = -n_out and tool x along x_hint projected."""
    z = -np.asarray(n_out, float)
    x = np.asarray(x_hint, float) - (np.asarray(x_hint) @ z) * z
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = p
    return T


def sphere_rows(center=(1000.0, 0.0, 100.0), radius=600.0, el_deg=(-10, 60), az_deg=(-40, 40),
                rows=4, pitch_mm=5.0, transition=4):
    """A boustrophedon path over rows of constant elevation on the seed patch."""
    c = np.asarray(center)
    poses, seg, pt, zone = [], [], [], []
    els = np.radians(np.linspace(el_deg[0], el_deg[1], rows))
    for i, el in enumerate(els):
        length = radius * np.cos(el) * np.radians(az_deg[1] - az_deg[0])
        n = int(round(length / pitch_mm)) + 1
        az = np.radians(np.linspace(az_deg[0], az_deg[1], n))
        if i % 2:
            az = az[::-1]
        if i > 0:  # transition from the previous row end, lifted 20 mm
            prev = poses[-1]
            n_next = np.array([-np.cos(el) * np.cos(az[0]), np.cos(el) * np.sin(az[0]), np.sin(el)])
            nxt = tool_pose(c + radius * n_next, n_next)
            for s in np.linspace(0, 1, transition + 2)[1:-1]:
                T = nxt.copy() if s > 0.5 else prev.copy()
                T[:3, 3] = (1 - s) * prev[:3, 3] + s * nxt[:3, 3] - 20.0 * T[:3, 2]
                poses.append(T); seg.append(i); pt.append(0); zone.append(ZONE_CODE["self_motion"])
        for j, a in enumerate(az):
            n_out = np.array([-np.cos(el) * np.cos(a), np.cos(el) * np.sin(a), np.sin(el)])
            poses.append(tool_pose(c + radius * n_out, n_out))
            seg.append(i); pt.append(j + 1); zone.append(ZONE_CODE["work"])
    return Path(np.array(poses), np.array(seg), np.array(pt), np.array(zone, dtype=np.int8),
                step_over_mm=0.0, pitch_mm=pitch_mm)
