"""What the tool does to the part (docs/process.md).

One module per job:

- ``footprint``: the tool's radial footprint (flat, parabolic, Gaussian, measured table), unit volume;
- ``surface_map``: the declared interface of a map's sites (grid cells, mesh vertices, several faces);
- ``grid``: the map's grid over the surface's (u, v) domain (cell areas, material mask, 3-D points);
- ``mesh_map``: the map on a free-form face's own mesh (a value per vertex, areas on the surface);
- ``map_set``: a map per face of several worked in one program, and all of them as one;
- ``maps``: which sites a surface gets, and the map of a TCP track or a trajectory on them;
- ``integrate``: the map integrated over the trajectory as the controller runs it (<= 4 ms samples);
- ``figures``: mean, PV, RMS, uniformity, edge roll-off, uncovered area; the PNG;
- ``stepover``: ``raster.step_over_mm = "auto"`` from the predicted map;
- ``dwell``: feed factors along the rows that meet a target removal map;
- ``outputs``: the run's hook (process_map.npz, report figures).
"""
