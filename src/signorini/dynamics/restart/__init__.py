"""Restart and rollback: the protocol every part with state across steps follows (:mod:`.protocol`) and the
checkpoint file, written atomically and read back with every field checked (:mod:`.checkpoint`).  Built on the
model, the solvers and the schemes."""
