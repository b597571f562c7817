"""The contact rows: B, the friction frames and the pairing of contact pairs (:mod:`.contact_rows`, their only
owner), and the rows of the current configuration under finite strain, which move with each Newton iterate
(:mod:`.current_rows`).  Built on the model; read by the step's solvers as ``ctx.rows``."""
