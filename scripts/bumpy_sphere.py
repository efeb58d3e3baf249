#!/usr/bin/env python3
"""Writes lapmesh::bumpy_sphere(level) (include/lapmesh/shapes.h) as an OFF file, same vertex
order and faces: an icosphere of radius 1 whose vertices are scaled by
1 + amplitude * sin(f x) sin(f y) sin(f z). Usage: bumpy_sphere.py LEVEL OUT.off"""
import math
import sys


def bumpy_sphere(level, amplitude=0.08, frequency=6.0):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    pts = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
           [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    tris = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
            (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
            (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]

    def project(p):
        n = math.sqrt(sum(c * c for c in p))
        return [c / n for c in p]

    pts = [project(p) for p in pts]
    for _ in range(level):
        mids = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in mids:
                pts.append(project([0.5 * (pts[a][k] + pts[b][k]) for k in range(3)]))
                mids[key] = len(pts) - 1
            return mids[key]

        nxt = []
        for f in tris:
            a, b, c = mid(f[0], f[1]), mid(f[1], f[2]), mid(f[2], f[0])
            nxt += [(f[0], a, c), (f[1], b, a), (f[2], c, b), (a, b, c)]
        tris = nxt
    out = []
    for p in pts:
        r = 1.0 + amplitude * math.sin(frequency * p[0]) * math.sin(frequency * p[1]) * math.sin(frequency * p[2])
        out.append([c * r for c in p])
    return out, tris


if __name__ == "__main__":
    level, path = int(sys.argv[1]), sys.argv[2]
    pts, tris = bumpy_sphere(level)
    with open(path, "w") as f:
        f.write("OFF\n%d %d 0\n" % (len(pts), len(tris)))
        for p in pts:
            f.write("%.17g %.17g %.17g\n" % tuple(p))
        for t in tris:
            f.write("3 %d %d %d\n" % t)
