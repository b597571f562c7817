"""Finite elements: meshes, reference cells, the dof map, materials and the vectorized assembly."""
