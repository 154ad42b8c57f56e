"""The path: raster S-paths and contour passes on a surface, several faces in one path, the Path box."""
