#!/usr/bin/env python3
"""Log-log plots of time against vertex count, one panel per operation and one line per library,
from the times.csv of one run of the side-by-side harness (the anchors harness; see
doc/benchmarks.md for how it is run).

    python3 scripts/anchors_plot.py TIMES_CSV OUT.svg [--title TEXT]

Each point is the median wall time of the candidate's timed rounds on one mesh. Needs
matplotlib (Debian: python3-matplotlib).
"""
import argparse
import collections
import csv
import math
import statistics

OPERATIONS = {
    "a": "a uniform Laplacian",
    "b": "b cotangent stiffness + mass",
    "c": "c mean curvature",
    "d": "d Gaussian curvature per area",
    "e": "e 30 smallest eigenpairs",
    "f": "f explicit smoothing x10",
    "g": "g implicit smoothing x10",
}
STYLE = {"lapmesh": ("k", "o"), "pmp": ("tab:blue", "s"), "libigl": ("tab:orange", "^"),
         "cgal": ("tab:green", "D"), "spectra": ("tab:red", "v"), "spectra-lu": ("tab:purple", "x")}


def medians(path):
    """{op: {candidate: [(vertices, median ms), ...]}} from a harness times.csv."""
    runs = collections.defaultdict(list)
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            ms = float(row["ms"] or "nan")
            if row["candidate"] != "*" and math.isfinite(ms):  # "*": the harness's note of a skipped operation
                runs[(row["op"], row["candidate"], int(row["vertices"]))].append(ms)
    out = collections.defaultdict(lambda: collections.defaultdict(list))
    for (op, candidate, vertices), times in sorted(runs.items()):
        out[op][candidate].append((vertices, statistics.median(times)))
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("times_csv")
    p.add_argument("out")
    p.add_argument("--title", default="")
    a = p.parse_args()
    import matplotlib
    import matplotlib.ticker

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plain = matplotlib.ticker.FuncFormatter(lambda v, _: "%g" % v)
    data = medians(a.times_csv)
    ops = [op for op in OPERATIONS if op in data]
    columns = 4 if len(ops) > 4 else len(ops)
    rows = (len(ops) + columns - 1) // columns
    fig, axes = plt.subplots(rows, columns, figsize=(3.2 * columns, 3.0 * rows), squeeze=False)
    for ax, op in zip(axes.flat, ops):
        for candidate, points in sorted(data[op].items(), key=lambda kv: (kv[0] != "lapmesh", kv[0])):
            colour, marker = STYLE.get(candidate, ("tab:gray", "."))
            x, y = zip(*points)
            ax.plot(x, y, color=colour, marker=marker, label=candidate, linewidth=2 if candidate == "lapmesh" else 1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(plain)
            axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_title(OPERATIONS[op], fontsize=9)
        ax.set_xlabel("vertices", fontsize=8)
        ax.set_ylabel("median wall time (ms)", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, which="both", linewidth=0.3)
        ax.legend(fontsize=7)
    for ax in list(axes.flat)[len(ops):]:
        ax.axis("off")
    if a.title:
        fig.suptitle(a.title, fontsize=10)
    fig.tight_layout()
    fig.savefig(a.out, metadata={"Date": None} if a.out.endswith(".svg") else None)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
