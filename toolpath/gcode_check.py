#!/usr/bin/env python3
"""Independent G-code reader for the toolpath tests (standard library only).

Usage: gcode_check.py PROGRAM.ngc CL.csv [--tol MM]

Reads an RS-274 program the way a grbl 1.1 / LinuxCNC controller would for the subset clpost
writes, refusing anything outside it: words G0 G1 G17 G21 G90 G94, M2 M3 M5 M8 M9 M30, X Y Z F S;
parenthesised comments; upper case; lines of at most 80 characters (grbl's line buffer); plain
decimal numbers (no exponents). It tracks the modal state (motion mode, position, feed) and
compares the motion with the CL data (photomill CSV: move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min):
every CL feed move must be one G1 line to the same point at the same feed, every CL rapid must be
reached by G0 lines (a post may split a rapid into a horizontal and a vertical part), and nothing
else may move the tool except G0 lines at the start and a final retract straight up.
Prints one summary line; exit 0 if consistent, 1 with the reason otherwise.
"""
import csv
import re
import sys

ALLOWED_G = {0, 1, 17, 21, 90, 94}
ALLOWED_M = {2, 3, 5, 8, 9, 30}
WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")


def fail(msg):
    print("gcode_check: " + msg)
    sys.exit(1)


def parse_program(path):
    """Returns the list of motions (mode, (x, y, z) with None for never-set axes, feed) and facts."""
    pos = [None, None, None]
    mode = None
    feed = None
    units_mm = absolute = False
    ended = False
    motions = []
    with open(path, encoding="ascii") as f:
        lines = f.read().split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    for n, raw in enumerate(lines, 1):
        where = "%s:%d" % (path, n)
        if len(raw) > 80:
            fail(where + ": line longer than 80 characters")
        if ended:
            if raw.strip() not in ("", "%"):
                fail(where + ": text after the program end")
            continue
        line = re.sub(r"\([^()]*\)", "", raw).strip()
        if "(" in line or ")" in line:
            fail(where + ": unbalanced comment")
        if line in ("", "%"):
            continue
        if line != line.upper():
            fail(where + ": lower-case word")
        rest = line.replace(" ", "")
        words = WORD.findall(rest)
        if "".join(a + b for a, b in words) != rest:
            fail(where + ": cannot parse '%s' (exponent or stray character?)" % line)
        target = list(pos)
        moved = False
        for letter, number in words:
            value = float(number)
            if letter == "G":
                if not number.isdigit() or int(number) not in ALLOWED_G:
                    fail(where + ": G%s is outside the grbl/LinuxCNC subset" % number)
                g = int(number)
                if g in (0, 1):
                    mode = g
                elif g == 21:
                    units_mm = True
                elif g == 90:
                    absolute = True
            elif letter == "M":
                if not number.isdigit() or int(number) not in ALLOWED_M:
                    fail(where + ": M%s is outside the grbl/LinuxCNC subset" % number)
                if int(number) in (2, 30):
                    ended = True
            elif letter in "XYZ":
                target["XYZ".index(letter)] = value
                moved = True
            elif letter == "F":
                if value <= 0:
                    fail(where + ": feed must be positive")
                feed = value
            elif letter == "S":
                if value < 0:
                    fail(where + ": negative spindle speed")
            else:
                fail(where + ": word %s is outside the subset" % letter)
        if moved:
            if mode is None:
                fail(where + ": motion without G0/G1")
            if not (units_mm and absolute):
                fail(where + ": motion before G21 and G90")
            if mode == 1 and feed is None:
                fail(where + ": G1 before any F word")
            pos = target
            motions.append((mode, tuple(pos), feed, where))
    if not ended:
        fail(path + ": no M2/M30 program end")
    return motions


def read_cl_csv(path):
    moves = []
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header = [h.strip() for h in rows[0]]
    col = {name: header.index(name) for name in ("move", "x_mm", "y_mm", "z_mm", "feed_mm_per_min")}
    for r in rows[1:]:
        kind = r[col["move"]].strip()
        xyz = tuple(float(r[col[c]]) for c in ("x_mm", "y_mm", "z_mm"))
        feed = float(r[col["feed_mm_per_min"]]) if kind == "feed" else None
        moves.append((kind, xyz, feed))
    return moves


def close(a, b, tol):
    return all(p is not None and abs(p - q) <= tol for p, q in zip(a, b))


def main():
    args = sys.argv[1:]
    tol = 1e-4
    if "--tol" in args:
        i = args.index("--tol")
        tol = float(args[i + 1])
        del args[i:i + 2]
    if len(args) != 2:
        fail("usage: gcode_check.py PROGRAM.ngc CL.csv [--tol MM]")
    motions = parse_program(args[0])
    cl = read_cl_csv(args[1])
    k = 0
    for index, (kind, xyz, feed) in enumerate(cl):
        here = motions[k - 1][1] if k > 0 else None
        if here is not None and close(here, xyz, tol):
            continue  # a move shorter than the program's resolution needs no line
        if kind == "feed":
            while index == 0 and k < len(motions) and motions[k][0] == 0:
                k += 1  # the post's own approach from the safe plane
            if k >= len(motions):
                fail("CL feed move to %s has no G1 line" % (xyz,))
            mode, pos, f, where = motions[k]
            if mode != 1 or not close(pos, xyz, tol) or abs(f - feed) > 0.05:
                fail("%s: expected G1 to %s F%g (CL feed move), found G%d to %s F%s" % (where, xyz, feed, mode, pos, f))
            k += 1
        else:
            while True:
                if k >= len(motions):
                    fail("CL rapid to %s is never reached" % (xyz,))
                mode, pos, f, where = motions[k]
                if mode != 0:
                    fail("%s: G1 while a CL rapid to %s was expected" % (where, xyz))
                k += 1
                if close(pos, xyz, tol):
                    break
    last = motions[k - 1][1] if k > 0 else None
    for mode, pos, f, where in motions[k:]:
        if mode != 0 or last is None or pos[0] != last[0] or pos[1] != last[1] or pos[2] < last[2]:
            fail("%s: motion after the last CL move that is not a retract straight up" % where)
        last = pos
    print("gcode_check: ok: %d CL moves matched by %d motion lines" % (len(cl), len(motions)))


if __name__ == "__main__":
    main()
