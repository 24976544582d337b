"""Repeat the reference packing n x n x n into a larger box, for throughput at larger N.

    python3 bench/tile_packing.py N OUT [PACKING(.gz)]

The copies are placed side by side: they are not settled against each other at the seams, so a
run on the result loses pressure and rebuilds its lists (a throughput figure, not a state).
"""
import gzip
import sys


def main() -> None:
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    n, out = int(sys.argv[1]), sys.argv[2]
    src = sys.argv[3] if len(sys.argv) > 3 else "bench/peers/common/packing.txt.gz"
    if n < 1:
        sys.exit(f"N = {n}: expected a repeat count >= 1")
    opener = gzip.open if src.endswith(".gz") else open
    head, rows = [], []
    with opener(src, "rt") as f:
        for line in f:
            if line.startswith("#"):
                head.append(line)
            elif line.strip():
                rows.append(line.split())
    L = float(next(h for h in head if h.startswith("# L_m=")).split("=")[1])
    with open(out, "w") as f:
        for h in head:
            if h.startswith("# L_m="):
                h = f"# L_m={n * L:.15e}\n"
            elif h.startswith("# N="):
                h = f"# N={n ** 3 * len(rows)}\n"
            f.write(h)
        k = 0
        for a in range(n):
            for b in range(n):
                for c in range(n):
                    for r in rows:
                        k += 1
                        x, y, z = float(r[1]) + a * L, float(r[2]) + b * L, float(r[3]) + c * L
                        f.write(f"{k} {x:.15e} {y:.15e} {z:.15e} {r[4]}\n")


if __name__ == "__main__":
    main()
