#!/usr/bin/env python3
# The table of scripts/bench-rough.sh: for each roughing program given as CL CSV (photomill's
# `move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min`), the CL moves, the feed path length (and the part
# of it at the plunge feed), the rapid length, and the cycle time: every feed move at its own
# feed rate plus the rapids at RAPID mm/min (an assumption: 5000 unless --rapid-mm-per-min),
# tool changes, accelerations and dwells not counted. Remaining stock, when a cutsim --report
# JSON is given, from that report.
#   bench_rough_table.py [--rapid-mm-per-min 5000] [--plunge-feed 300] \
#       NAME:CL.csv:WALL_S[:CUTSIM.json] ...
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
    """(left p95, left max, into allowance, below surface) from a cutsim --report JSON; the keys
    are looked up loosely since the report's schema is cutsim's."""
    if not path:
        return None
    with open(path) as f:
        rep = json.load(f)
    flat = {}

    def walk(o, prefix=""):
        if isinstance(o, dict):
            for k, v in o.items():
                walk(v, prefix + k + ".")
        elif isinstance(o, (int, float)):
            flat[prefix[:-1]] = o
    walk(rep)
    return flat


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--rapid-mm-per-min", type=float, default=5000)
    ap.add_argument("--plunge-feed", type=float, default=300)
    ap.add_argument("--cutsim-keys", default="",
                    help="comma-separated report keys for left p95, left max, into allowance, "
                         "below surface")
    ap.add_argument("programs", nargs="+")
    a = ap.parse_args()
    keys = [k for k in a.cutsim_keys.split(",") if k]
    head = ["program", "CL moves", "feed m", "at plunge feed m", "rapid m", "at feed min",
            "cycle min", "compute s"]
    if keys:
        head += ["left p95 mm", "left max mm", "into allowance mm", "below surface mm"]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for spec in a.programs:
        parts = spec.split(":")
        name, csv, wall = parts[0], parts[1], parts[2]
        s = cl_stats(csv, a.rapid_mm_per_min, a.plunge_feed)
        row = [name, "%d" % s["moves"], "%.1f" % s["feed_m"], "%.2f" % s["plunge_m"],
               "%.1f" % s["rapid_m"], "%.1f" % s["feed_min"], "%.1f" % s["cycle_min"], wall]
        if keys:
            flat = cutsim_cols(parts[3] if len(parts) > 3 else "")
            for k in keys:
                v = flat.get(k) if flat else None
                row.append("%.3f" % v if v is not None else "-")
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
