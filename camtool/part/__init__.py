"""The part: read workpieces (meshes, clouds, STEP), fit, segment into faces, surfaces, boundaries and edges."""
