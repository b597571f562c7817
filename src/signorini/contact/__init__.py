"""Contact: rigid obstacles, the nodal contact set, complementarity and the per-step solver."""
