#!/usr/bin/env python3
# The table of scripts/bench-rough.sh: for each roughing program given as CL CSV (photomill's
# `move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min`), the CL moves, the feed path length (and the part
# of it at the plunge feed), the rapid length, and the cycle time: every feed move at its own
# feed rate plus the rapids at RAPID mm/min (an assumption: 5000 unless --rapid-mm-per-min),
# tool changes, accelerations and dwells not counted. Remaining stock, with --cutsim, from each
# program's cutsim --report JSON; with --crosscheck, the vertical cut into the allowance and
# below the surface from scripts/zmap_crosscheck.py's table (a cross-check, not cutsim).
#   bench_rough_table.py [--rapid-mm-per-min 5000] [--plunge-feed 300] [--cutsim] \
#       [--crosscheck XCHECK.txt] NAME:CL.csv:WALL_S[:CUTSIM.json] ...
import argparse
import json
import math
import sys


def cl_stats(path, rapid_feed, plunge_feed):
    moves = feed_len = plunge_len = rapid_len = feed_min = 0.0
    moves = 0
    prev = None
    with open(path) as f:
        header = f.readline().strip()
        if header != "move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min":
            raise SystemExit("%s: not a CL CSV (header %r)" % (path, header))
        for n, line in enumerate(f, 2):
            c = line.rstrip("\n").split(",")
            if len(c) != 8:
                raise SystemExit("%s:%d: expected 8 columns, got %d" % (path, n, len(c)))
            p = (float(c[1]), float(c[2]), float(c[3]))
            moves += 1
            if prev is not None:
                d = math.dist(prev, p)
                if c[0] == "rapid":
                    rapid_len += d
                else:
                    fd = float(c[7])
                    feed_len += d
                    feed_min += d / fd
                    if abs(fd - plunge_feed) < 1e-9:
                        plunge_len += d
            prev = p
    return {
        "moves": moves,
        "feed_m": feed_len / 1000,
        "plunge_m": plunge_len / 1000,
        "rapid_m": rapid_len / 1000,
        "feed_min": feed_min,
        "cycle_min": feed_min + rapid_len / rapid_feed,
    }


def cutsim_cols(path):
    """From a cutsim --report JSON (one program): material left above surface + allowance along
    the normal (p95, max), the deepest gouge below the surface along the normal, rapids and
    plunges into material."""
    if not path:
        return ["-"] * 4
    with open(path) as f:
        rep = json.load(f)
    prog = rep["programs"][0]
    return ["%.3f" % rep["left"]["p95_mm"], "%.3f" % rep["left"]["max_mm"],
            "%.3f" % rep["gouge"]["max_mm"],
            "%d / %d" % (prog["rapids_into_material"], prog["plunges"])]


def crosscheck_cols(path, csv):
    """From zmap_crosscheck.py's table: into allowance and below surface (vertical) of `csv`."""
    if not path:
        return []
    with open(path) as f:
        for line in f:
            c = [v.strip() for v in line.strip().strip("|").split("|")]
            if c and c[0] == csv:
                return [c[3], c[4]]
    return ["-", "-"]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rapid-mm-per-min", type=float, default=5000)
    ap.add_argument("--plunge-feed", type=float, default=300)
    ap.add_argument("--cutsim", action="store_true", help="the specs carry cutsim reports")
    ap.add_argument("--crosscheck", default="", help="zmap_crosscheck.py's output")
    ap.add_argument("programs", nargs="+")
    a = ap.parse_args()
    head = ["program", "CL moves", "feed m", "at plunge feed m", "rapid m", "at feed min",
            "cycle min", "compute s"]
    if a.cutsim:
        head += ["left p95 mm", "left max mm", "gouge mm", "rapids / plunges into material"]
    if a.crosscheck:
        head += ["x-check: into allowance mm", "x-check: below surface mm"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for spec in a.programs:
        parts = spec.split(":")
        name, csv, wall = parts[0], parts[1], parts[2]
        s = cl_stats(csv, a.rapid_mm_per_min, a.plunge_feed)
        row = [name, "%d" % s["moves"], "%.1f" % s["feed_m"], "%.2f" % s["plunge_m"],
               "%.1f" % s["rapid_m"], "%.1f" % s["feed_min"], "%.1f" % s["cycle_min"], wall]
        if a.cutsim:
            row += cutsim_cols(parts[3] if len(parts) > 3 else "")
        row += crosscheck_cols(a.crosscheck, csv)
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
