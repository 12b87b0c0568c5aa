"""Writing conforming meshes: OpenFOAM cases, VTU files; their quality figures."""
