"""Assembly of S and M on the 3D box n x n x 10n (Q1 hexahedra): seconds and peak memory.

Usage: python benchmarks/bench_assembly.py [n ...]   (default 8 16 32)
Each size runs in a fresh process so that peak RSS is per size.
"""

import json
import resource
import subprocess
import sys
import time


def one(n: int) -> dict:
    from signorini.fem.assembly import mass_matrix, node_pattern, stiffness_matrix
    from signorini.fem.material import IsotropicElastic
    from signorini.fem.mesh import box

    mesh = box(n, n, 10 * n, 0.1, 0.1, 1.0)
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    node_pattern(mesh)
    t1 = time.perf_counter()
    S = stiffness_matrix(mesh, IsotropicElastic(0.25, 0.5, 1.0))
    t2 = time.perf_counter()
    M = mass_matrix(mesh, 1.0)
    t3 = time.perf_counter()
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    csr = sum(A.data.nbytes + A.indices.nbytes + A.indptr.nbytes for A in (S, M))
    # second, "warm" pass in the same process: memory pages are already mapped, so this
    # measures the algorithm without the first-touch page faults of fresh memory
    del S, M
    mesh._cache.clear()
    w0 = time.perf_counter()
    node_pattern(mesh)
    stiffness_matrix(mesh, IsotropicElastic(0.25, 0.5, 1.0))
    mass_matrix(mesh, 1.0)
    warm = time.perf_counter() - w0
    return {
        "n": n,
        "elements": mesh.n_cells,
        "dofs": 3 * mesh.n_nodes,
        "pattern_s": t1 - t0,
        "stiffness_s": t2 - t1,
        "mass_s": t3 - t2,
        "total_s": t3 - t0,
        "s_per_million_elements": (t3 - t0) / mesh.n_cells * 1e6,
        "warm_s": warm,
        "warm_s_per_million_elements": warm / mesh.n_cells * 1e6,
        "csr_MB": csr / 1e6,
        "peak_increase_MB": (rss1 - rss0) / 1e3,
        "peak_over_csr": (rss1 - rss0) * 1e3 / csr,
    }


if __name__ == "__main__":
    if len(sys.argv) > 2 and sys.argv[1] == "--one":
        print(json.dumps(one(int(sys.argv[2]))))
        sys.exit()
    sizes = [int(a) for a in sys.argv[1:]] or [8, 16, 32]
    print(
        f"{'n':>3} {'elements':>9} {'dofs':>9} {'total s':>8} {'s/Mel':>6} {'warm s':>7} {'warm s/Mel':>10} "
        f"{'CSR MB':>8} {'peak/CSR':>8}"
    )
    for n in sizes:
        r = json.loads(subprocess.check_output([sys.executable, __file__, "--one", str(n)]))
        print(
            f"{r['n']:>3} {r['elements']:>9} {r['dofs']:>9} {r['total_s']:>8.2f} "
            f"{r['s_per_million_elements']:>6.2f} {r['warm_s']:>7.2f} {r['warm_s_per_million_elements']:>10.2f} "
            f"{r['csr_MB']:>8.1f} {r['peak_over_csr']:>8.2f}"
            f"   (pattern {r['pattern_s']:.2f}s, S {r['stiffness_s']:.2f}s, M {r['mass_s']:.2f}s)"
        )
