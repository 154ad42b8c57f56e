"""``feasible_region.png``: where the workpiece can go, over the two most varied placement variables.

Each cell of the screened grid shows the best (lowest) screen cost over the
other variables; a cell where no placement passed the screen is grey, light
for "within the wrist-centre bound but some pose outside the joint limits",
dark for "some pose beyond the wrist-centre reach bound". Refinement
placements are small dots, the planned candidates numbered, the chosen one a
star and the user's placement a triangle. With one variable the plot is the
cost along it.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .. import safe_io


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plotted_variables(study) -> list[int]:
    """Indices (into study.variables) of the two most varied variables: the most grid values, then x, y, z, yaw."""
    order = sorted(range(len(study.variables)), key=lambda i: (-len(study.grid[i]), study.variables[i].axis))
    return sorted(order[:2])


def _edges(values: np.ndarray) -> np.ndarray:
    v = np.asarray(values, float)
    if len(v) == 1:
        return np.array([v[0] - 0.5, v[0] + 0.5])
    mid = 0.5 * (v[1:] + v[:-1])
    return np.concatenate([[2 * v[0] - mid[0]], mid, [2 * v[-1] - mid[-1]]])


def plot_feasible_region(study, file: Path) -> Path:
    """The PNG (module doc); returns its path."""
    from ..files import output_file

    plt = _plt()
    V = study.variables
    idx = plotted_variables(study)
    user = study.zero
    fig, ax = plt.subplots(figsize=(7.2, 5.6))
    label = [f"{V[i].name} offset ({V[i].unit})" for i in idx]
    if len(idx) == 2:
        xy = _draw_map(fig, ax, study, idx)
        ax.set_ylabel(label[1])
    else:
        xy = _draw_costs(ax, study, idx[0])
        ax.set_ylabel("screen cost (s)")
    _draw_placements(ax, study, xy, user)
    ax.set_xlabel(label[0])
    others = [v.name for i, v in enumerate(V) if i not in idx]
    title = f"{study.robot_name}: feasible workpiece placements (screen)"
    if others:
        title += f"\nbest over {', '.join(others)}"
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, loc="best", framealpha=0.85)
    ax.grid(alpha=0.25)
    fig.tight_layout()
    file = output_file(file)
    safe_io.save_figure(fig, file, dpi=110)
    plt.close(fig)
    return file


def _grid_map(study, a: int, b: int):
    """(best cost, state) per cell of the screened grid over variables ``a`` (columns) and ``b`` (rows):
    state 0 beyond the bound, 1 outside the limits, 2 feasible (the best over the other variables)."""
    V, results = study.variables, study.results
    ga, gb = study.grid[a], study.grid[b]
    cost = np.full((len(gb), len(ga)), np.nan)
    state = np.zeros((len(gb), len(ga)), int)       # 0 beyond the bound, 1 outside limits, 2 feasible
    pos_a = {round(float(x), 6): i for i, x in enumerate(ga)}
    pos_b = {round(float(x), 6): i for i, x in enumerate(gb)}
    for off in study.grid_offsets:
        r = results[off]
        i, j = pos_a[round(off[V[a].axis], 6)], pos_b[round(off[V[b].axis], 6)]
        s = 2 if r.feasible else (0 if r.stage == "bound" else 1)
        state[j, i] = max(state[j, i], s)
        if r.feasible:
            cost[j, i] = np.fmin(cost[j, i], r.cost)
    return cost, state


def _draw_map(fig, ax, study, idx):
    """The map over two variables: the grid's cells (grey where infeasible, the cost where feasible) and the
    refinement placements; the plot's (x, y) of a placement."""
    V, results = study.variables, study.results
    a, b = idx
    ga, gb = study.grid[a], study.grid[b]
    cost, state = _grid_map(study, a, b)
    shade = np.where(state == 0, 0.35, 0.75)
    ax.pcolormesh(_edges(ga), _edges(gb), np.ma.masked_where(state == 2, shade), cmap="gray", vmin=0, vmax=1,
                  shading="flat")
    if np.isfinite(cost).any():
        mesh = ax.pcolormesh(_edges(ga), _edges(gb), np.ma.masked_invalid(cost), cmap="viridis_r", shading="flat")
        fig.colorbar(mesh, ax=ax, label="screen cost (s): lower is better")
    xs = [o[V[a].axis] for o in results if o not in study.grid_offsets]
    ys = [o[V[b].axis] for o in results if o not in study.grid_offsets]
    ax.scatter(xs, ys, s=6, color="white", edgecolors="black", linewidths=0.3, label="refinement", zorder=3)

    def xy(o):
        return o[V[a].axis], o[V[b].axis]
    return xy


def _draw_costs(ax, study, a: int):
    """The best screen cost along one variable (infeasible values marked); the plot's (x, y) of a placement."""
    V, results = study.variables, study.results
    ga = np.array(sorted({o[V[a].axis] for o in results}))
    best = {}
    for o, r in results.items():
        k = o[V[a].axis]
        best[k] = min(best.get(k, np.inf), r.cost)
    c = np.array([best[k] for k in ga])
    ok = np.isfinite(c)
    ax.plot(ga[ok], c[ok], ".-", color="tab:blue", label="best screen cost")
    base = float(c[ok].min()) if ok.any() else 0.0
    if (~ok).any():
        ax.scatter(ga[~ok], np.full(int((~ok).sum()), base), marker="x", color="0.4", label="infeasible")

    def xy(o):
        k = o[V[a].axis]
        v = best.get(k, np.inf)
        return k, v if np.isfinite(v) else base
    return xy


def _draw_placements(ax, study, xy, user) -> None:
    """The planned candidates numbered (a cross where the plan failed), the chosen one a star, the user's a
    triangle."""
    verified = study.verified
    for n, o in enumerate([o for o in verified if o != user], 1):
        x, y = xy(o)
        mark = "o" if verified[o]["ok"] else "X"
        ax.scatter([x], [y], marker=mark, s=70, facecolors="none", edgecolors="tab:red", zorder=4)
        ax.annotate(str(n), (x, y), textcoords="offset points", xytext=(5, 5), fontsize=8, color="tab:red")
    if study.chosen is not None:
        x, y = xy(study.chosen)
        ax.scatter([x], [y], marker="*", s=260, color="gold", edgecolors="black", label="chosen", zorder=5)
    x, y = xy(user)
    ax.scatter([x], [y], marker="^", s=110, color="tab:purple", edgecolors="black", label="your placement", zorder=5)
