"""Writes an n x n grid of squares (two triangles each, v and f lines only) as OBJ, for
the large-file figures of perf/log/overview.md: python3 perf/grid_obj.py N OUT.obj"""

import sys
n = int(sys.argv[1]); out = sys.argv[2]
with open(out, 'w') as f:
    w = f.write
    w(f"# {n}x{n} grid, {2*n*n} triangles\n")
    for j in range(n + 1):
        w("".join(f"v {i*0.001:.6f} {((i*7+j*13)%17)*0.0001:.6f} {j*0.001:.6f}\n" for i in range(n + 1)))
    for j in range(n):
        row = []
        for i in range(n):
            a = j*(n+1) + i + 1; b = a + 1; c = a + n + 1; d = c + 1
            row.append(f"f {a} {b} {d}\nf {a} {d} {c}\n")
        w("".join(row))
