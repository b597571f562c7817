"""Benchmarks, exact solutions, convergence studies, comparisons of schemes and masses, the report of reproduce."""
