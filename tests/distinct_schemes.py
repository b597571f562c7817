"""The registered schemes, less the entries that repeat another one at their default options."""

from signorini.dynamics.schemes import SCHEMES

# At their defaults newmark (beta = 1/4, gamma = 1/2) is crank-nicolson and theta (theta = 1) is
# backward-euler (test_schemes.py checks that they reproduce them): a test over every scheme would
# run those two cases twice.
REPEATS = {"newmark": "crank-nicolson", "theta": "backward-euler"}
DISTINCT_SCHEMES = [name for name in SCHEMES.names(aliases=False) if name not in REPEATS]
