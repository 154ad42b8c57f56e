"""Figures of a design study, after the paper's Figures 5 and 6.

- ``design_space.png``: the design variables (the first two), step 1 (the
  invalid set, the explored particles, the narrowed box) beside step 2
  (particles inside the box, the obstacles, the Pareto set, the chosen and the
  reference designs). NSGA-II studies show one panel.
- ``pareto_front.png``: length (mm) against singularities for every valid
  evaluation, the front, the chosen and the reference designs, and other
  fronts (e.g. NSGA-II) when given.
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


def _xy(X, names):
    """The plotted coordinates: the first two variables, or (variable, index) with one."""
    X = np.asarray(X, float).reshape(-1, len(names))
    if len(names) >= 2:
        return X[:, 0], X[:, 1]
    return X[:, 0], np.zeros(len(X))


def plot_design_space(study, file: Path) -> Path:
    """PNG of the design space of each optimisation step (Figures 5-6)."""
    plt = _plt()
    names = study.names
    steps = [1, 2] if study.method == "mopso" else [1]
    fig, axes = plt.subplots(1, len(steps), figsize=(6.2 * len(steps), 5.2), squeeze=False)
    bad = study.violation > 0
    ylab = f"{names[1]} mm" if len(names) >= 2 else "(one variable)"
    for ax, step in zip(axes[0], steps):
        sel = study.step == step
        inv = bad & (sel if step == 1 else (study.step <= step))
        ok = ~bad & sel
        x, y = _xy(study.X[inv], names)
        ax.scatter(x, y, marker="x", color="tab:red", s=30, label="invalid (obstacle)")
        x, y = _xy(study.X[ok], names)
        ax.scatter(x, y, s=14, color="tab:blue" if step == 2 else "0.45", label="valid particles")
        if step == 2 or study.method != "mopso":
            x, y = _xy(study.front_X, names)
            ax.scatter(x, y, s=34, facecolors="none", edgecolors="black", label="Pareto set")
        if study.narrowed_lower is not None and len(names) >= 2:
            lo, hi = study.narrowed_lower, study.narrowed_upper
            ax.add_patch(plt.Rectangle((lo[0], lo[1]), hi[0] - lo[0], hi[1] - lo[1], fill=False,
                                       linestyle="--", color="tab:green", label="narrowed ranges"))
        if step == steps[-1]:
            if study.chosen_X is not None:
                x, y = _xy(study.chosen_X, names)
                ax.scatter(x, y, marker="*", s=220, color="gold", edgecolors="black", label="chosen", zorder=5)
            if study.reference_X is not None:
                x, y = _xy(study.reference_X, names)
                ax.scatter(x, y, marker="^", s=90, color="tab:purple", edgecolors="black",
                           label="reference (job's arm)", zorder=5)
        ax.set_xlim(study.lower[0], study.upper[0])
        if len(names) >= 2:
            ax.set_ylim(study.lower[1], study.upper[1])
        ax.set_xlabel(f"{names[0]} mm")
        ax.set_ylabel(ylab)
        title = {1: "step 1: explore (invalid set)", 2: "step 2: optimise in narrowed ranges"}[step]
        ax.set_title(title if study.method == "mopso" else "NSGA-II evaluations")
        ax.legend(fontsize=7, loc="best", framealpha=0.85)
        ax.grid(alpha=0.3)
    return _save(plt, fig, file)


def _save(plt, fig, file) -> Path:
    """Write a figure as PNG (its folder made) and close it."""
    from ..files import output_file

    fig.tight_layout()
    file = output_file(file)
    safe_io.save_figure(fig, file, dpi=110)
    plt.close(fig)
    return file


def plot_front(study, file: Path, others: dict | None = None) -> Path:
    """PNG of the objective space: valid evaluations, the front(s), chosen and reference."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.5, 4.8))
    ok = study.violation == 0
    ax.scatter(study.F[ok, 0], study.F[ok, 1], s=10, color="0.7", label="valid evaluations")
    ax.step(study.front_F[:, 0], study.front_F[:, 1], where="post", color="black", linewidth=1)
    ax.scatter(study.front_F[:, 0], study.front_F[:, 1], s=30, color="black", label=f"{study.method} front")
    for (label, F), colour in zip((others or {}).items(), ("tab:orange", "tab:cyan", "tab:pink")):
        F = np.asarray(F, float).reshape(-1, 2)
        ax.scatter(F[:, 0], F[:, 1], s=40, marker="s", facecolors="none", edgecolors=colour, label=label)
    if study.chosen_coarse is not None:
        ax.scatter([study.chosen_coarse.length_mm], [study.chosen_coarse.singularities], marker="*", s=220,
                   color="gold", edgecolors="black", label="chosen", zorder=5)
    if study.reference_coarse is not None and study.reference_coarse.valid:
        ax.scatter([study.reference_coarse.length_mm], [study.reference_coarse.singularities], marker="^",
                   s=90, color="tab:purple", edgecolors="black", label="reference (job's arm)", zorder=5)
    ax.set_xlabel("F1: total arm length (mm)")
    ax.set_ylabel("F2: singularities on the coarse raster")
    ax.set_title("Pareto front (valid designs only)")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _save(plt, fig, file)


def plot_design_html(study, file: Path) -> Path:
    """design.html: the design space and the Pareto front as interactive plotly figures (offline page)."""
    import plotly.graph_objects as go

    from ..report.html import fig_html, write_html_page

    names = study.names
    bad = study.violation > 0
    space = go.Figure()
    for label, sel, style in (("invalid (obstacle)", bad, {"symbol": "x", "color": "#d62728", "size": 7}),
                              ("valid particles", ~bad, {"color": "#1f77b4", "size": 5})):
        x, y = _xy(study.X[sel], names)
        space.add_trace(go.Scatter(x=x, y=y, mode="markers", name=label, marker=style))
    for label, X, style in (("Pareto set", study.front_X, {"symbol": "circle-open", "color": "black", "size": 9}),
                            ("chosen", study.chosen_X, {"symbol": "star", "color": "gold", "size": 16}),
                            ("reference (job's arm)", study.reference_X, {"symbol": "triangle-up",
                                                                           "color": "#9467bd", "size": 11})):
        if X is not None and len(np.atleast_1d(X)):
            x, y = _xy(X, names)
            space.add_trace(go.Scatter(x=x, y=y, mode="markers", name=label, marker=style))
    space.update_layout(xaxis_title=f"{names[0]} mm", yaxis_title=f"{names[1]} mm" if len(names) > 1 else "",
                        height=520, margin={"l": 60, "r": 20, "t": 30, "b": 50})
    front = go.Figure()
    ok = study.violation == 0
    front.add_trace(go.Scatter(x=study.F[ok, 0], y=study.F[ok, 1], mode="markers", name="valid evaluations",
                               marker={"color": "#aaaaaa", "size": 5}))
    front.add_trace(go.Scatter(x=study.front_F[:, 0], y=study.front_F[:, 1], mode="lines+markers",
                               line={"shape": "hv", "color": "black"}, name=f"{study.method} front"))
    front.update_layout(xaxis_title="F1: total arm length (mm)", yaxis_title="F2: singularities (coarse raster)",
                        height=480, margin={"l": 60, "r": 20, "t": 30, "b": 50})
    return write_html_page(file, f"camtool design: {study.method}", [
        ("Design space", '<p class="note">The design variables of every evaluation (the first two).</p>',
         fig_html(space, "camtool-design-space")),
        ("Pareto front", '<p class="note">Length against singularities of the valid designs.</p>',
         fig_html(front, "camtool-pareto-front"))])
