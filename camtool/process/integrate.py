"""The process map integrated over the program as the controller runs it.

The timed trajectory is resampled at ``dt_s`` (<= 4 ms, the motion check's
step: ``sample_trajectory``), its TCP positions come from batched forward
kinematics (``camtool.motion.fk_batch``), and every interval between two
samples whose TCP is within ``contact_tol_mm`` of the surface at both ends acts
on the part at its midpoint: leads, corners, dwell and transitions that touch
the part count like the rows. Each interval carries an amount (volume-like,
um * mm^2):

- polish, grind (Preston): ``k_p * F * v * dt`` with v the abrasive's speed
  (``relative_speed_m_s``) or, when 0, the TCP's own travel over the interval;
- paint: ``deposition_mm3_s * dt``;
- inspect: 1 per interval, and the map counts the runs (contiguous stretches in
  contact) whose footprint covers each cell.

The amount is spread by the footprint in the surface's tangent plane at the
contact (the tool is taken to comply with the surface, tilt ignored).
On a plane the footprint is shift-invariant: the amounts are binned
bilinearly into the grid and convolved with the footprint's kernel
(``scipy.signal.fftconvolve``). On a sphere patch the cells' size and the
tangent plane change with the elevation v, but a shift in azimuth u is an
isometry: each grid row gets its own kernel from the exact geometry (the
footprint in the tangent plane of a contact on that row, per cell area) and
the binned amounts of the row are convolved with it along u
(``row-convolution``). ``method = "direct"`` sums each contact's footprint over
its window of cells in its own tangent plane (any surface, no binning; the
reference the tests and the benchmark compare with), normalised per contact
so each one puts exactly its amount on the surface.

Except for inspect, the map is integrated on the grid refined across the rows
(``grid.refinement``: ``RIPPLE_SAMPLES`` samples per period of the ripple
between passes), each contact spread along its stretch of path first
(``_along_path``); ``ProcessMap.values`` are the sub-cells' averages over each
cell of ``process.grid_mm`` and ``ProcessMap.fine`` the refined map the figures
are taken on (docs/process.md, "What uniformity_within_5pct is, exactly").
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..motion.fk_batch import BatchFK
from ..settings import ProcessSettings
from ..trajectory import sample_trajectory
from .footprint import Footprint
from .grid import RIPPLE_SAMPLES, MapGrid, block_mean, map_grid, refined, refinement


def _fftconvolve(*args, **kwargs):
    """``scipy.signal.fftconvolve``, imported on first use: scipy.signal costs ~0.6 s of every run's start-up."""
    from scipy.signal import fftconvolve

    return fftconvolve(*args, **kwargs)

UM_MM2_PER_M3 = 1e12 * 1e3  # 1 m^3 = 1e9 mm^3; depth mm -> um is 1e3 (amount in um*mm^2 is mm^3 * 1e3)
QUANTITY = {"polish": ("removal depth", "um"), "grind": ("removal depth", "um"),
            "paint": ("film thickness", "um"), "inspect": ("coverage count", "passes")}
CHUNK = 2000  # contacts per vectorised block of the direct sums


@dataclass(frozen=True)
class Contacts:
    """Intervals of the motion in which the tool acts: midpoints (uv, world mm, normal), amounts, run ids."""

    uv: np.ndarray
    point_mm: np.ndarray
    normal: np.ndarray
    amount: np.ndarray     # um * mm^2 (inspect: 1)
    run: np.ndarray        # contiguous stretch in contact, 0..
    dt_s: np.ndarray
    travel_mm: np.ndarray


@dataclass(frozen=True)
class ProcessMap:
    """A map over ``grid``: ``values`` (nv, nu) of ``quantity`` in ``units``, and how it was made."""

    grid: MapGrid
    values: np.ndarray
    kind: str
    quantity: str
    units: str
    method: str
    contact_time_s: float
    contact_length_mm: float
    samples: int
    fine: "ProcessMap | None" = None  # the map on the refined grid the figures are taken on (``grid.refined``)


def amounts(settings: ProcessSettings, dt_s: np.ndarray, travel_mm: np.ndarray) -> np.ndarray:
    """What each interval puts on the part (um * mm^2; 1 for inspect)."""
    if settings.kind in ("polish", "grind"):
        if settings.relative_speed_m_s > 0:
            sliding_m = settings.relative_speed_m_s * dt_s
        else:
            sliding_m = travel_mm / 1000.0
        # depth rate k_p * p * v integrated over the footprint: volume rate k_p * F * v (m^3/s)
        return settings.preston_coefficient_per_pa * settings.force_n * sliding_m * 1e9 * 1e3
    if settings.kind == "paint":
        return settings.deposition_mm3_s * dt_s * 1e3
    return np.ones_like(dt_s)


def contacts_from_tcp(settings: ProcessSettings, surface, t_s: np.ndarray, tcp_mm: np.ndarray,
                      spacing_mm: float = 0.0) -> Contacts:
    """The acting intervals of a TCP track sampled at ``t_s`` (see the module doc).

    ``spacing_mm`` > 0: consecutive intervals of one run are merged into one contact per
    ``spacing_mm`` of travel (at their amount-weighted centroid, amounts summed), which
    keeps the direct sums' cost at the path length over the grid's resolution rather than
    the sample count; a tool at rest stays one contact.
    """
    t_s, tcp_mm = np.asarray(t_s, float), np.asarray(tcp_mm, float)
    uv = surface.uv_from_points(tcp_mm)
    foot = surface.point_mm(uv[:, 0], uv[:, 1])
    normal = surface.normal_at(uv[:, 0], uv[:, 1])
    off = np.einsum("ij,ij->i", tcp_mm - foot, normal)
    on = np.abs(off) <= settings.contact_tol_mm
    dt = np.diff(t_s)
    act = on[:-1] & on[1:] & (dt > 0)
    k = np.flatnonzero(act)
    mid = 0.5 * (tcp_mm[k] + tcp_mm[k + 1])
    travel = np.linalg.norm(tcp_mm[k + 1] - tcp_mm[k], axis=1)
    run = np.cumsum(np.r_[True, np.diff(k) > 1]) - 1 if len(k) else np.zeros(0, int)
    amount, dtk = amounts(settings, dt[k], travel), dt[k]
    if spacing_mm > 0 and len(k):
        start = np.r_[True, run[1:] != run[:-1]]
        cum = np.cumsum(travel)
        cum_run = cum - np.repeat(cum[start] - travel[start], np.diff(np.r_[np.flatnonzero(start), len(k)]))
        key = run.astype(np.int64) * (1 << 32) + np.floor(cum_run / spacing_mm).astype(np.int64)
        first = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
        w = np.maximum(amount, 1e-300)
        mid = np.add.reduceat(mid * w[:, None], first, axis=0) / np.add.reduceat(w, first)[:, None]
        amount, dtk = np.add.reduceat(amount, first), np.add.reduceat(dtk, first)
        travel, run = np.add.reduceat(travel, first), run[first]
    muv = surface.uv_from_points(mid) if len(mid) else np.zeros((0, 2))
    mfoot = surface.point_mm(muv[:, 0], muv[:, 1])
    mnormal = surface.normal_at(muv[:, 0], muv[:, 1])
    return Contacts(muv, mfoot, mnormal, amount, run, dtk, travel)


def tcp_track(trajectory, robot, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(t_s, TCP mm in the world frame) of ``trajectory`` resampled at ``dt_s``, FK batched."""
    samples = sample_trajectory(trajectory, dt_s)
    return samples.t_s, BatchFK(robot)(samples.q).tcp


def _bin_bilinear(grid: MapGrid, uv: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Bilinear binning of weights at uv into the grid (what lands off the grid is dropped)."""
    nv, nu = grid.shape
    f = grid.index_of(uv)
    i0 = np.floor(f).astype(np.int64)
    fr = f - i0
    acc = np.zeros(nv * nu)
    for du, dv in ((0, 0), (1, 0), (0, 1), (1, 1)):
        iu, iv = i0[:, 0] + du, i0[:, 1] + dv
        w = (fr[:, 0] if du else 1 - fr[:, 0]) * (fr[:, 1] if dv else 1 - fr[:, 1])
        ok = (iu >= 0) & (iu < nu) & (iv >= 0) & (iv < nv)
        acc += np.bincount(iv[ok] * nu + iu[ok], weights=(weights * w)[ok], minlength=nv * nu)
    return acc.reshape(nv, nu)


ALONG_PATH_SUBSTEPS = 8  # points per cell that a contact's stretch of path is spread over before binning


def _along_path(grid: MapGrid, c: Contacts) -> tuple[np.ndarray, np.ndarray]:
    """(uv, amounts): each contact's amount spread evenly over the stretch of path it stands for (half-way to its
    neighbours in its run), at points ``ALONG_PATH_SUBSTEPS`` per cell apart. Binning the contacts as points
    aliases their spacing against the cells' (a few % per cell, 0.2 % on the ripple's peaks); the stretches
    tile the path, so each cell gets the length of path it holds."""
    n = len(c.uv)
    if n < 2:
        return c.uv, c.amount
    same = c.run[1:] == c.run[:-1]
    step = np.where(same[:, None], np.diff(c.uv, axis=0), 0.0)              # to the next contact, in its run
    fwd = np.vstack([step, np.zeros((1, 2))])
    back = np.vstack([np.zeros((1, 2)), step])
    lo, hi = -0.5 * back, 0.5 * fwd                                          # the stretch round each contact
    cells = np.max(np.abs(hi - lo) / np.array([grid.du, grid.dv]), axis=1)
    k = np.clip(np.ceil(ALONG_PATH_SUBSTEPS * cells), 1, 64).astype(np.int64)
    owner = np.repeat(np.arange(n), k)
    first = np.repeat(np.cumsum(k) - k, k)
    f = (np.arange(len(owner)) - first + 0.5) / k[owner]
    uv = c.uv[owner] + lo[owner] + f[:, None] * (hi - lo)[owner]
    return uv, c.amount[owner] / k[owner]


def _convolved(grid: MapGrid, fp: Footprint, uv, weights, binary: bool = False) -> np.ndarray:
    """Per unit area: binned weights convolved with the footprint's kernel (plane grids)."""
    kernel = (fp.kernel(grid.cell_mm) if grid.sub == (1, 1)
              else fp.cell_kernel(grid.du, grid.dv, max(KERNEL_SUB_MM, fp.radius_mm / SUB_PER_RADIUS)))
    if binary:
        kernel = (kernel > 0).astype(float)
    out = _fftconvolve(_bin_bilinear(grid, uv, weights), kernel, mode="same")
    return out if binary else out / grid.area_mm2


ROW_SUPERSAMPLE = 3  # sub-samples per cell side of a sphere row's kernel (at least; ROW_SUB_MM apart at most)
KERNEL_SUB_MM = 0.05  # sub-sample spacing of the plane kernels of refined grids: a flat footprint's chords to ~0.03 mm
SUB_PER_RADIUS = 500  # ... or the footprint's radius over this, if coarser (a 1 m spray: 1 mm, not 10^4 sub-samples)
CLOSED_FORM = ("flat", "parabolic")  # footprints whose sphere row kernels are integrated in closed form
ROW_SUB_MM = 0.25     # the same for the sphere's row kernels (one per cell row: 40x the work of a plane's one)


def _row_kernel_closed(grid: MapGrid, fp: Footprint, v0: float, hu: int, hv: int) -> np.ndarray:
    """(2hv+1, 2hu+1) the flat or parabolic footprint of a contact at (u = 0, v0) on a sphere, at each cell row's
    elevation and averaged over each cell in u, in closed form: in the tangent plane at the contact a point
    (U, V) is r = R sqrt(1 - q^2) away, q = A cos U + B with A = cos V cos v0, B = sin V sin v0, so r <= a is
    |U| <= U* (cos U* = (sqrt(1 - a^2/R^2) - B) / A) and 1 - r^2/a^2 integrates over U as a trigonometric
    polynomial. Written here: scipy has no footprint integrals, and supersampling to the same accuracy costs
    a hundred times more (a flat footprint's chords must be right to ~0.03 mm for the ripple's peaks)."""
    R, a = float(grid.surface.radius_mm), fp.radius_mm
    V = v0 + np.arange(-hv, hv + 1) * grid.dv
    A = (np.cos(V) * math.cos(v0))[:, None]
    B = (np.sin(V) * math.sin(v0))[:, None]
    cos_star = (math.sqrt(max(1.0 - (a / R) ** 2, 0.0)) - B) / A
    u_star = np.where(cos_star >= 1.0, 0.0, np.arccos(np.clip(cos_star, -1.0, 1.0)))
    edges = (np.arange(-hu, hu + 2) - 0.5) * grid.du
    lo = np.clip(edges[None, :-1], -u_star, u_star)
    hi = np.clip(edges[None, 1:], -u_star, u_star)
    if fp.profile == "flat":
        return (hi - lo) / grid.du

    def q2(U):  # integral of (A cos U + B)^2 dU
        return A * A * (0.5 * U + 0.25 * np.sin(2.0 * U)) + 2.0 * A * B * np.sin(U) + B * B * U

    k = (R / a) ** 2
    return np.maximum((1.0 - k) * (hi - lo) + k * (q2(hi) - q2(lo)), 0.0) / grid.du


def _row_kernel(grid: MapGrid, fp: Footprint, iv0: float, binary: bool) -> tuple[np.ndarray, int, int]:
    """(kernel, hu, hv) of a contact on grid row ``iv0`` of a sphere patch, in cell offsets: the footprint in the
    tangent plane at (u = 0, v_iv0), averaged over each cell, weighted so that sum(kernel * area) = 1."""
    surface = grid.surface
    R, a = float(surface.radius_mm), fp.radius_mm
    v0 = grid.v[0] + iv0 * grid.dv
    v_far = min(abs(v0) + (a + grid.cell_mm) / R, 0.5 * math.pi)
    hu = int(math.ceil(a / (R * max(math.cos(v_far), 0.05) * grid.du))) + 1
    hv = int(math.ceil(a / (R * grid.dv))) + 1
    mu = mv = ROW_SUPERSAMPLE
    if grid.sub != (1, 1) and not binary:
        if fp.profile in CLOSED_FORM:
            w = _row_kernel_closed(grid, fp, v0, hu, hv)
            rows = np.arange(-hv, hv + 1) + iv0
            area = R * R * np.cos(grid.v[0] + rows * grid.dv) * grid.du * grid.dv
            return w / max(float(np.sum(w * area[:, None])), 1e-300), hu, hv
        sub_mm = max(ROW_SUB_MM, 5 * a / SUB_PER_RADIUS)  # sub-samples ROW_SUB_MM apart (or a / 100)
        mu = max(mu, int(math.ceil(R * math.cos(v0) * grid.du / sub_mm)))
        mv = max(1, int(math.ceil(R * grid.dv / sub_mm)))
    du = (np.arange(-hu, hu + 1)[:, None] + ((np.arange(mu) + 0.5) / mu - 0.5)[None, :]).ravel() * grid.du
    dv = (np.arange(-hv, hv + 1)[:, None] + ((np.arange(mv) + 0.5) / mv - 0.5)[None, :]).ravel() * grid.dv
    U, V = np.meshgrid(du, v0 + dv)
    # in the patch frame: the contact at azimuth 0 (azimuth shifts are isometries of the sphere)
    p = R * np.stack([np.cos(V) * np.cos(U), np.cos(V) * np.sin(U), np.sin(V)], axis=-1)
    n = np.array([math.cos(v0), 0.0, math.sin(v0)])
    d = p - R * n
    d = d - (d @ n)[..., None] * n
    w = fp.shape(np.linalg.norm(d, axis=-1)).reshape(2 * hv + 1, mv, 2 * hu + 1, mu).mean(axis=(1, 3))
    if binary:
        return (w > 0).astype(float), hu, hv
    rows = np.arange(-hv, hv + 1) + iv0
    area = R * R * np.cos(grid.v[0] + rows * grid.dv) * grid.du * grid.dv
    return w / max(float(np.sum(w * area[:, None])), 1e-300), hu, hv


def _row_convolved(grid: MapGrid, fp: Footprint, uv, weights, binary: bool = False) -> np.ndarray:
    """Per unit area on a sphere patch: the binned weights of each grid row convolved along u with that row's
    kernel (``_row_kernel``; exact geometry per elevation, shift-invariant in azimuth). On a refined grid, with a
    footprint of no closed form, the m_v sub-rows of one cell share the kernel of the cell's centre."""
    nv, nu = grid.shape
    binned = _bin_bilinear(grid, uv, weights)
    out = np.zeros((nv, nu))
    band = 1 if binary or fp.profile in CLOSED_FORM else grid.sub[1]  # closed-form kernels are cheap: one per row
    active = np.any(binned != 0, axis=1)
    for b0 in range(0, nv, band):
        b1 = min(b0 + band, nv)
        if not active[b0:b1].any():
            continue
        kernel, hu, hv = _row_kernel(grid, fp, 0.5 * (b0 + b1 - 1), binary)
        rows = _fftconvolve(binned[b0:b1], kernel, mode="full")[:, hu:hu + nu]  # (b1 - b0 + 2hv, nu)
        lo, hi = b0 - hv, b1 + hv
        a, b = max(lo, 0), min(hi, nv)
        out[a:b] += rows[a - lo:rows.shape[0] - (hi - b)]
    return out


def _direct(grid: MapGrid, fp: Footprint, c: Contacts, weights, binary: bool = False) -> np.ndarray:
    """Per unit area: each contact's footprint on its window of cells, in its tangent plane (any surface)."""
    surface = grid.surface
    nv, nu = grid.shape
    a = fp.radius_mm

    def window(e):
        """Cell offsets round the contacts ``e``: the footprint's reach in cells where they are."""
        if surface.model == "sphere":
            R = float(surface.radius_mm)
            v_far = float(np.max(np.abs(c.uv[e, 1]))) + (a + grid.cell_mm) / R
            hu = int(math.ceil(a / (R * max(math.cos(min(v_far, 0.5 * math.pi)), 0.05) * grid.du))) + 1
            hv = int(math.ceil(a / (R * grid.dv))) + 1
        else:
            hu, hv = int(math.ceil(a / grid.du)) + 1, int(math.ceil(a / grid.dv)) + 1
        ou, ov = np.meshgrid(np.arange(-hu, hu + 1), np.arange(-hv, hv + 1))
        return ou.ravel(), ov.ravel()

    acc = np.zeros(nv * nu)
    centre = np.rint(grid.index_of(c.uv)).astype(np.int64)
    for s in range(0, len(weights), CHUNK):
        e = slice(s, s + CHUNK)
        ou, ov = window(e)
        iu = centre[e, 0:1] + ou[None, :]
        iv = centre[e, 1:2] + ov[None, :]
        u = grid.u[0] + iu * grid.du
        v = grid.v[0] + iv * grid.dv
        d = surface.point_mm(u, v) - c.point_mm[e, None, :]
        n = c.normal[e, None, :]
        d = d - np.sum(d * n, axis=-1, keepdims=True) * n
        w = fp.shape(np.linalg.norm(d, axis=-1))
        if binary:
            w = (w > 0).astype(float)
        else:
            area = (surface.radius_mm ** 2 * np.cos(v) * grid.du * grid.dv if surface.model == "sphere"
                    else np.full(w.shape, grid.du * grid.dv))
            w = w / np.maximum(np.sum(w * area, axis=1, keepdims=True), 1e-300)
        w = w * weights[e, None]
        ok = (iu >= 0) & (iu < nu) & (iv >= 0) & (iv < nv) & (w > 0)
        acc += np.bincount((iv * nu + iu)[ok], weights=w[ok], minlength=nv * nu)
    return acc.reshape(nv, nu)


def map_from_contacts(settings: ProcessSettings, grid: MapGrid, c: Contacts, method: str = "auto") -> tuple[np.ndarray, str]:
    """(values, method): the map of ``c`` on ``grid``; method auto = convolution on a plane, direct sums else."""
    fp = Footprint.from_settings(settings)
    if method == "auto":
        method = "convolution" if grid.surface.model == "plane" else "row-convolution"
    if method == "row-convolution" and grid.surface.model != "sphere":
        raise ValueError("row-convolution is for sphere patches")
    conv = {"convolution": _convolved, "row-convolution": _row_convolved}.get(method)
    spread = None if conv is None else (lambda uv, w, **kw: conv(grid, fp, uv, w, **kw))
    if settings.kind != "inspect":
        if spread is not None:
            return spread(*(_along_path(grid, c) if grid.sub != (1, 1) else (c.uv, c.amount))), method
        return _direct(grid, fp, c, c.amount), method
    count = np.zeros(grid.shape)
    for r in np.unique(c.run):
        sel = c.run == r
        if spread is not None:
            hit = spread(c.uv[sel], np.ones(int(sel.sum())), binary=True)
        else:
            sub = Contacts(c.uv[sel], c.point_mm[sel], c.normal[sel], c.amount[sel], c.run[sel], c.dt_s[sel],
                           c.travel_mm[sel])
            hit = _direct(grid, fp, sub, np.ones(int(sel.sum())), binary=True)
        count += hit > 0.5
    return count, method


def across_rows_mm(surface, c: Contacts) -> np.ndarray:
    """Unit (u, v) direction, in mm along u and v, across the contacts' travel: the normal to the principal axis
    of their steps (travel-weighted); (0, 1) when the tool never moves."""
    if len(c.uv) < 2:
        return np.array([0.0, 1.0])
    same = np.diff(c.run) == 0
    d = np.diff(c.uv, axis=0)[same]
    if surface.model == "sphere":  # rad to mm on the surface
        R = float(surface.radius_mm)
        d = d * np.column_stack([R * np.cos(c.uv[1:, 1]), np.full(len(c.uv) - 1, R)])[same]
    length = np.linalg.norm(d, axis=1)
    keep = length > 0
    if not keep.any():
        return np.array([0.0, 1.0])
    e = d[keep] / length[keep, None]
    along = np.linalg.eigh(np.einsum("k,ki,kj->ij", length[keep], e, e))[1][:, -1]
    return np.array([-along[1], along[0]])


def process_map(settings: ProcessSettings, surface, t_s, tcp_mm, method: str = "auto",
                grid: MapGrid | None = None, rows_mm: float = 0.0, refine: bool = True) -> ProcessMap:
    """The map of a TCP track (``tcp_track``) over ``surface``'s worked area.

    ``rows_mm``: the rows' spacing (the ripple's period; 0 = not a raster: the footprint's radius). Except
    for inspect, the map is integrated on the grid refined across the rows to ``RIPPLE_SAMPLES`` samples per
    period (``grid.refinement``); ``values`` are its cell averages and ``fine`` the refined map.
    ``refine = False``: the values at the grid's own cell centres (no figures of the ripple)."""
    if grid is None:
        grid = map_grid(surface, settings.grid_mm, 0.5 * settings.diameter_mm + 2 * settings.grid_mm)
    c = contacts_from_tcp(settings, surface, t_s, tcp_mm, spacing_mm=0.5 * grid.cell_mm)
    quantity, units = QUANTITY[settings.kind]
    m_u = m_v = 1
    if refine and settings.kind != "inspect":  # coverage counts have no ripple to resolve
        period = rows_mm if rows_mm > 0 else 0.5 * settings.diameter_mm
        m_u, m_v = refinement(grid, period / RIPPLE_SAMPLES, across_rows_mm(surface, c))
    made = (settings.kind, quantity, units)
    run = (float(c.dt_s.sum()), float(c.travel_mm.sum()), int(len(t_s)))
    if (m_u, m_v) == (1, 1):
        values, used = map_from_contacts(settings, grid, c, method)
        return ProcessMap(grid, values, *made, used, *run)
    fine_grid = refined(grid, m_u, m_v)
    values, used = map_from_contacts(settings, fine_grid, c, method)
    fine = ProcessMap(fine_grid, values, *made, used, *run)
    return ProcessMap(grid, block_mean(values, m_u, m_v), *made, used, *run, fine=fine)


def trajectory_map(settings: ProcessSettings, surface, trajectory, robot, dt_s: float,
                   method: str = "auto", grid: MapGrid | None = None, rows_mm: float = 0.0) -> ProcessMap:
    """The map of a timed trajectory as the controller runs it (resampled at ``dt_s``)."""
    t_s, tcp = tcp_track(trajectory, robot, dt_s)
    return process_map(settings, surface, t_s, tcp, method, grid=grid, rows_mm=rows_mm)
