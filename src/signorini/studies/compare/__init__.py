"""``signorini compare``: a matrix of time schemes x mass variants on one problem, ranked.

Pure functions, in the order the command calls them:

1. :func:`parse_schemes` / :func:`parse_masses`: ``cn,generalized-alpha[rho_inf=0.5]``
   and ``standard,seed`` into validated :class:`SchemeSpec` and mass names (registry
   names and options; an unknown one is an :class:`InputError` listing the allowed ones).
2. :func:`plan_benchmark` / :func:`plan_case`: the runs (pairs x levels, plus the
   reference run of a 2D/3D benchmark), every level's dt checked (T must be an integer
   multiple of it) before anything runs.
3. :func:`run_plan`: runs them, serially or in ``jobs`` processes
   (:class:`concurrent.futures.ProcessPoolExecutor`; every run is a pure function of its
   job, so the numbers do not depend on ``jobs``), measures the errors (1D: exact
   solution, :func:`~signorini.studies.study.errors_1d`; 2D/3D: the reference,
   :func:`~signorini.studies.reference_study.relative_errors`), the least-squares rates
   and the per-run diagnostics of :meth:`History.summary`, and ranks the pairs
   (:func:`rank_pairs`).  A pair that cannot run on this problem (a mass variant that
   refuses the mesh, a scheme that refuses a mass: an :class:`InputError` raised by the
   run itself) is kept as "n/a: <reason>".
4. :func:`write_report`: ``compare.md`` (one ranking table), ``compare.json`` and the
   figures with their CSVs (:mod:`signorini.studies.plots`).

Ranking rule (:data:`RANK_KEYS`, :func:`rank_pairs`): lexicographic with tolerance
bands.  Pairs are sorted by the error of the displacement in L2(0,T; H1) at the finest
level; pairs whose errors lie within 10% of the best error of their band are tied on
that key and ordered by the next key: the energy drift max |E - E0| / E0 (10%, or both
below 1e-9), then the oscillation index of the first impact (within 0.05), then the
maximum penetration (10%, or both below 1e-12 x the body's size).  Pairs tied on every
key share a rank.  A missing value (n/a) sorts after every number.  Case files have no
error: the ranking starts at the energy drift.  The time per step is reported, never
ranked (it depends on the machine and its load, so the ranking would not be
reproducible).  Why not a rank sum: it gives the same weight to a round-off
penetration of 1e-17 vs 2e-17 as to a factor 10 in the error, and its result changes
when a pair is added or removed; the lexicographic rule puts accuracy first and uses
the diagnostics only to separate pairs that are equally accurate.
"""

from .collect import _pair_entry, _reference, collect, fitted_rate, run_plan  # noqa: F401
from .names import (  # noqa: F401
    Pair,
    SchemeSpec,
    _num,
    _split_top_level,
    make_pairs,
    parse_masses,
    parse_reference,
    parse_scheme,
    parse_schemes,
)
from .plan import (  # noqa: F401
    CONTACT_NORM,
    DEFAULT_LEVELS,
    DEFAULT_N0,
    DEFAULT_RATIO,
    DEFAULT_T,
    BenchmarkTarget,
    CaseTarget,
    Plan,
    _cost,
    _length_scale,
    _steps,
    estimate_plan,
    make_jobs,
    plan_benchmark,
    plan_case,
)
from .pool import (  # noqa: F401
    SUMMARY_FIELDS,
    TIMING_FIELDS,
    Job,
    Outcome,
    _context,
    _watch_parent,
    default_jobs,
    execute_job,
    run_jobs,
)
from .ranking import (  # noqa: F401
    CONTACT_TOLERANCE,
    RANK_KEYS,
    RANK_LABELS,
    RANKING_RULE,
    RANKING_RULE_CASE,
    _finite,
    rank_pairs,
    rank_result,
    ranked_pairs,
)
from .render import (  # noqa: F401
    COLUMN_NOTES,
    _cell,
    _f,
    reference_text,
    report_markdown,
    setup_text,
    strip_timings,
    table_markdown,
    write_report,
)
