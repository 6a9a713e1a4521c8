#!/usr/bin/env python3
"""Independent APT CL reader for the toolpath tests (standard library only).

Usage: apt_check.py PATH.cl CL.csv

Reads APT CL text the way a conservative post-processor does, refusing anything outside the
subset photomill promises (docs/formats.md): one record per line, a major word, '/' and
comma-separated arguments; numbers in plain fixed notation only (digits, an optional point:
no exponent, no 'inf' or 'nan'); the tool selected (LOADTL/n) and described (CUTTER/d,r) before
the first motion; the spindle started (SPINDL/RPM,n,CLW) before the first feed move when a
spindle record exists; FEDRAT before the first feed move; END then FINI as the last records.
Compares the motion with the CL data in photomill's CSV (move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min):
the same moves, in order, each of the same kind (a GOTO after RAPID is a rapid), to the same
point exactly (both files write numbers that read back to the same double), at the same feed.
Prints one summary line; exit 0 if consistent, 1 with the reason otherwise.
"""
import csv
import re
import sys

NUMBER = re.compile(r"^[+-]?(?:\d+\.?\d*|\.\d+)$")
KNOWN = {"PARTNO", "UNITS", "LOADTL", "CUTTER", "SPINDL", "COOLNT", "FEDRAT", "RAPID", "GOTO", "END", "FINI"}


def fail(msg):
    print("apt_check: " + msg)
    sys.exit(1)


def number(text, where):
    text = text.strip()
    if not NUMBER.match(text):
        fail(f"{where}: '{text}' is not a plain fixed-point number")
    return float(text)


def parse_apt(path):
    with open(path, encoding="ascii") as f:
        records = [(n, line.strip()) for n, line in enumerate(f.read().split("\n"), 1)]
    records = [(n, r) for n, r in records if r and not r.startswith("$$")]
    if len(records) < 2 or records[-2][1] != "END" or records[-1][1] != "FINI":
        fail("the program does not end with END, FINI")
    tool = None
    loaded = False
    spindle_records = any(r.startswith("SPINDL/RPM") for _, r in records)
    spindle_on = False
    feed = None
    rapid_next = False
    moves = []
    for n, r in records:
        where = f"{path}:{n}"
        word, _, rest = r.partition("/")
        word = word.strip()
        if word not in KNOWN:
            fail(f"{where}: unknown record '{word}'")
        args = [a.strip() for a in rest.split(",")] if rest else []
        if word == "LOADTL":
            number(args[0], where)
            loaded = True
        elif word == "CUTTER":
            if len(args) != 2:
                fail(f"{where}: CUTTER takes d,r")
            tool = (number(args[0], where), number(args[1], where))
        elif word == "UNITS":
            if args != ["MM"]:
                fail(f"{where}: units {args}, not MM")
        elif word == "SPINDL":
            if args and args[0] == "RPM":
                if number(args[1], where) <= 0 or args[2:] not in (["CLW"], ["CCLW"]):
                    fail(f"{where}: bad spindle record")
                spindle_on = True
            elif args == ["OFF"]:
                spindle_on = False
            else:
                fail(f"{where}: bad spindle record")
        elif word == "FEDRAT":
            if len(args) != 2 or args[0] != "MMPM":
                fail(f"{where}: expected FEDRAT/MMPM,f")
            feed = number(args[1], where)
        elif word == "RAPID":
            rapid_next = True
        elif word == "GOTO":
            if not loaded or tool is None:
                fail(f"{where}: a motion before the tool is loaded (LOADTL) and described (CUTTER)")
            if len(args) not in (3, 6):
                fail(f"{where}: GOTO takes 3 or 6 numbers")
            xyz = tuple(number(a, where) for a in args[:3])
            if rapid_next:
                moves.append(("rapid", xyz, 0.0))
            else:
                if feed is None:
                    fail(f"{where}: a feed move before any FEDRAT")
                if spindle_records and not spindle_on:
                    fail(f"{where}: a feed move with the spindle off")
                moves.append(("feed", xyz, feed))
            rapid_next = False
    return moves, tool


def parse_csv(path):
    moves = []
    with open(path, newline="") as f:
        for row in csv.DictReader(ln for ln in f if not ln.startswith("#")):
            xyz = (float(row["x_mm"]), float(row["y_mm"]), float(row["z_mm"]))
            feed = float(row["feed_mm_per_min"]) if row["move"] == "feed" else 0.0
            moves.append((row["move"], xyz, feed))
    return moves


def main():
    if len(sys.argv) != 3:
        print(__doc__)
        sys.exit(2)
    apt, tool = parse_apt(sys.argv[1])
    ref = parse_csv(sys.argv[2])
    if len(apt) != len(ref):
        fail(f"{len(apt)} moves in the APT file, {len(ref)} in the CSV")
    for k, (a, b) in enumerate(zip(apt, ref)):
        if a != b:
            fail(f"move {k}: APT {a}, CSV {b}")
    print(f"apt_check: {len(apt)} moves agree; tool d {tool[0]} r {tool[1]}; plain fixed-point numbers only")


if __name__ == "__main__":
    main()
