#!/usr/bin/env python3
"""Independent G-code reader for the toolpath tests (standard library only).

Usage: gcode_check.py PROGRAM.ngc [CL.csv CL2.csv ...] [--dialect D] [--tol MM] [--path-tol MM]
                      [--offset DX,DY,DZ] [--spindle-off-ok]

Reads an RS-274 program the way the controller of --dialect would, refusing every word outside
that controller's documented word set (WORD_SETS below, with the document each comes from) and
what clpost must never write: lower case, exponents, lines over 80 characters (grbl's line
buffer), motion before G21 and G90, a feed move (G1 G2 G3) while the spindle is not turning (no
M3 with S > 0 since the last M5 / tool change), M6 without T, G43 without H; for fanuc: '%' first
and last, an O number, a decimal point in every coordinate and feed, at most 3 decimals (IS-B);
for grbl: no '%'. It tracks the modal state (motion mode, position, feed, G2/G3 with incremental
I J in the XY plane) and compares the motion with the CL data (photomill CSV:
move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min; several files: one per tool, in order; --offset is
subtracted from them, the program's origin in the CL frame). By default every CL feed move must be
one G1 line to the same point at the same feed (--tol); with --path-tol every CL feed point must
lie within that distance of the posted path (lines and arcs, the one in progress or the next),
for programs with fitted arcs. Every CL rapid must be reached by G0 lines; nothing else may move
the tool except G0 lines before a tool's first move and retracts straight up.
Without CL files only the program is read (the word set, the modes, the spindle before the feeds).
Prints one summary line; exit 0 if consistent, 1 with the reason otherwise.
"""
import csv
import math
import re
import sys


def _r(a, b):
    return set(range(a, b + 1))


# The documented word sets. G and M codes as numbers (G91.1 -> 91.1); letters: every address.
WORD_SETS = {
    # The words grbl 1.1 and LinuxCNC both accept: what clpost wrote before it had dialects.
    "generic": {
        "source": "intersection of the grbl and linuxcnc sets below",
        "G": {0, 1, 2, 3, 17, 21, 90, 94} | _r(54, 59),
        "M": {0, 2, 3, 5, 8, 9, 30},
        "letters": set("GMXYZIJFS"),
    },
    "grbl": {
        "source": "https://github.com/gnea/grbl/blob/master/README.md (List of Supported G-Codes in Grbl v1.1); "
                  "https://github.com/gnea/grbl/wiki/Grbl-v1.1-Commands",
        "G": {0, 1, 2, 3, 4, 10, 17, 18, 19, 20, 21, 28, 28.1, 30, 30.1, 38.2, 38.3, 38.4, 38.5, 40, 43.1, 49, 53,
              61, 80, 90, 91, 91.1, 92, 92.1, 93, 94} | _r(54, 59),
        "M": {0, 1, 2, 3, 4, 5, 7, 8, 9, 30},
        "letters": set("GMFIJKLNPRSTXYZ"),
    },
    "linuxcnc": {
        "source": "https://linuxcnc.org/docs/2.9/html/gcode/overview.html (G-code table, M-code table)",
        "G": {0, 1, 2, 3, 4, 5, 5.1, 5.2, 5.3, 7, 8, 10, 17, 17.1, 18, 18.1, 19, 19.1, 20, 21, 28, 28.1, 30, 30.1, 33,
              33.1, 38.2, 38.3, 38.4, 38.5, 40, 41, 41.1, 42, 42.1, 43, 43.1, 43.2, 49, 53, 59.1, 59.2, 59.3, 61,
              61.1, 64, 70, 71, 72, 73, 74, 76, 90, 90.1, 91, 91.1, 92, 92.1, 92.2, 92.3, 93, 94, 95, 96, 97, 98,
              99} | _r(54, 59) | _r(80, 89),
        "M": _r(0, 9) | {19, 30, 48, 49, 50, 51, 52, 53, 60, 61} | _r(62, 68) | _r(70, 73) | _r(100, 199),
        "letters": set("ABCDFGHIJKLMNPQRSTUVWXYZ"),
    },
    # The CNC's own M codes are M00 M01 M02 M30 M98 M99; M03-M09 are the machine builder's, with
    # these meanings on every Fanuc-controlled mill we know (and in Haas's manual).
    "fanuc": {
        "source": "FANUC Series 0i-MD Operator's Manual B-64304EN (list of G codes, program configuration); "
                  "Haas Mill Operator's Manual (M-codes)",
        "G": {0, 1, 2, 3, 4, 9, 10, 11, 15, 16, 17, 18, 19, 20, 21, 22, 23, 27, 28, 29, 30, 31, 33, 37, 39, 40, 41,
              42, 43, 44, 45, 46, 47, 48, 49, 50, 51, 50.1, 51.1, 52, 53, 54.1, 60, 61, 62, 63, 64, 65, 66, 67, 68,
              69, 73, 74, 76, 90, 91, 92, 94, 95, 96, 97, 98, 99} | _r(54, 59) | _r(80, 89),
        "M": {0, 1, 2, 3, 4, 5, 6, 8, 9, 30, 98, 99},
        "letters": set("OGMNXYZABCUVWIJKRFSTHDPQL"),
    },
    "mach3": {
        "source": "Using Mach3Mill (ArtSoft, rev 1.84), chapter 10: G-code and M-code tables",
        "G": {0, 1, 2, 3, 4, 10, 12, 13, 15, 16, 17, 18, 19, 20, 21, 28, 28.1, 30, 31, 40, 41, 42, 43, 44, 49, 50,
              51, 52, 53, 60, 61, 64, 68, 69, 70, 71, 73, 90, 91, 92, 92.1, 93, 94, 95, 98, 99} | _r(54, 59) |
             _r(80, 89),
        "M": _r(0, 9) | {30, 47, 48, 49, 98, 99},
        "letters": set("ABCDFGHIJKLMNOPQRSTUVWXYZ"),
    },
}
WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")


def fail(msg):
    print("gcode_check: " + msg)
    sys.exit(1)


def code(number):
    v = float(number)
    return int(v) if v == int(v) else v


def parse_program(path, dialect, spindle_check):
    """Returns the list of motions (mode, (x, y, z), feed, where, start, centre)."""
    ws = WORD_SETS[dialect]
    pos = [None, None, None]
    mode = None
    feed = None
    units_mm = absolute = False
    ended = False
    spindle_on = False
    speed = 0.0
    tool_selected = False
    motions = []
    with open(path, encoding="ascii") as f:
        lines = f.read().split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    if dialect == "fanuc":
        if len(lines) < 3 or lines[0] != "%" or not re.fullmatch(r"O\d{1,4}", lines[1]) or lines[-1] != "%":
            fail(path + ": a Fanuc program is '%', 'O<number>', ..., '%'")
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
        if line == "%" and dialect == "grbl":
            fail(where + ": grbl 1.1 does not accept '%'")
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
        centre = None
        ij = {}
        gs = set()
        letters = {}
        for letter, number in words:
            if letter not in ws["letters"]:
                fail(where + ": word %s is outside the %s word set" % (letter, dialect))
            if dialect == "fanuc":
                if letter in "XYZIJKRF" and "." not in number:
                    fail(where + ": %s%s without a decimal point (Fanuc reads it in least input increments)" % (letter, number))
                if letter in "XYZIJKR" and "." in number and len(number.split(".")[1]) > 3:
                    fail(where + ": %s%s has more than 3 decimals (Fanuc IS-B)" % (letter, number))
                if letter in "GMSTHDON" and "." in number and letter != "G":
                    fail(where + ": %s%s must be an integer" % (letter, number))
            value = float(number)
            letters[letter] = value
            if letter == "G":
                g = code(number)
                if g not in ws["G"]:
                    fail(where + ": G%s is outside the %s word set" % (number, dialect))
                gs.add(g)
                if g in (0, 1, 2, 3):
                    mode = g
                elif g == 21:
                    units_mm = True
                elif g == 90:
                    absolute = True
            elif letter == "M":
                m = code(number)
                if m not in ws["M"]:
                    fail(where + ": M%s is outside the %s word set" % (number, dialect))
                if m in (2, 30):
                    ended = True
                elif m == 3:
                    spindle_on = True
                elif m in (5, 6, 0):
                    spindle_on = False if m != 0 else spindle_on
                if m == 6 and not (tool_selected or "T" in letters):
                    fail(where + ": M6 without a T word")
                if m == 0:
                    spindle_on = False  # the operator changes the tool; the program must start it again
            elif letter in "XYZ":
                target["XYZ".index(letter)] = value
                moved = True
            elif letter in "IJ":
                ij[letter] = value
            elif letter == "F":
                if value <= 0:
                    fail(where + ": feed must be positive")
                feed = value
            elif letter == "S":
                if value < 0:
                    fail(where + ": negative spindle speed")
                speed = value
            elif letter == "T":
                tool_selected = True
        if 43 in gs and "H" not in letters:
            fail(where + ": G43 without an H word")
        if spindle_on and speed <= 0:
            spindle_on = False
        if moved:
            if mode is None:
                fail(where + ": motion without G0/G1/G2/G3")
            if not (units_mm and absolute):
                fail(where + ": motion before G21 and G90")
            if mode != 0 and feed is None:
                fail(where + ": G%d before any F word" % mode)
            if mode != 0 and spindle_check and not spindle_on:
                fail(where + ": feed move G%d while the spindle is not turning (S > 0 and M3 first)" % mode)
            start = tuple(pos)
            if mode in (2, 3):
                if None in start or "I" not in ij and "J" not in ij:
                    fail(where + ": arc without a known start or I J")
                centre = (start[0] + ij.get("I", 0.0), start[1] + ij.get("J", 0.0))
                r0 = math.hypot(start[0] - centre[0], start[1] - centre[1])
                r1 = math.hypot(target[0] - centre[0], target[1] - centre[1])
                if abs(r0 - r1) > 0.002:
                    fail(where + ": arc radius at the start %.5f and at the end %.5f differ" % (r0, r1))
            pos = target
            motions.append((mode, tuple(pos), feed, where, start, centre))
    if not ended:
        fail(path + ": no M2/M30 program end")
    return motions


def read_cl_csv(path, offset):
    moves = []
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header = [h.strip() for h in rows[0]]
    col = {name: header.index(name) for name in ("move", "x_mm", "y_mm", "z_mm", "feed_mm_per_min")}
    for n, r in enumerate(rows[1:]):
        kind = r[col["move"]].strip()
        xyz = tuple(float(r[col[c]]) - o for c, o in zip(("x_mm", "y_mm", "z_mm"), offset))
        feed = float(r[col["feed_mm_per_min"]]) if kind == "feed" else None
        moves.append((kind, xyz, feed, n == 0))
    return moves


def close(a, b, tol):
    return all(p is not None and abs(p - q) <= tol for p, q in zip(a, b))


def distance_to_motion(q, motion):
    """Distance from point q to the segment or XY arc of a motion."""
    mode, end, _, _, start, centre = motion
    if None in start:
        return math.dist(q, end)
    if mode in (0, 1):
        d = [e - s for s, e in zip(start, end)]
        dd = sum(c * c for c in d)
        t = 0.0 if dd == 0 else max(0.0, min(1.0, sum((a - s) * c for a, s, c in zip(q, start, d)) / dd))
        return math.dist(q, [s + t * c for s, c in zip(start, d)])
    # Arc in the XY plane at constant Z (clpost fits no helices): the sweep from start to end,
    # clockwise for G2; q's angle inside it -> radial and Z distance, else the nearer end.
    a0 = math.atan2(start[1] - centre[1], start[0] - centre[0])
    a1 = math.atan2(end[1] - centre[1], end[0] - centre[0])
    aq = math.atan2(q[1] - centre[1], q[0] - centre[0])
    sign = 1 if mode == 3 else -1
    sweep = (sign * (a1 - a0)) % (2 * math.pi)
    along = (sign * (aq - a0)) % (2 * math.pi)
    if along <= sweep:
        r = math.hypot(start[0] - centre[0], start[1] - centre[1])
        return math.hypot(math.hypot(q[0] - centre[0], q[1] - centre[1]) - r, q[2] - start[2])
    return min(math.dist(q, start), math.dist(q, end))


def main():
    args = sys.argv[1:]
    opts = {"--tol": "1e-4", "--path-tol": None, "--dialect": "generic", "--offset": "0,0,0"}
    for name in list(opts):
        if name in args:
            i = args.index(name)
            opts[name] = args[i + 1]
            del args[i:i + 2]
    spindle_check = "--spindle-off-ok" not in args
    args = [a for a in args if a != "--spindle-off-ok"]
    if len(args) < 1 or opts["--dialect"] not in WORD_SETS:
        fail("usage: gcode_check.py PROGRAM.ngc [CL.csv ...] [--dialect %s] [--tol MM] [--path-tol MM] "
             "[--offset DX,DY,DZ] [--spindle-off-ok]" % "|".join(WORD_SETS))
    tol = float(opts["--tol"])
    path_tol = float(opts["--path-tol"]) if opts["--path-tol"] else None
    offset = [float(v) for v in opts["--offset"].split(",")]
    motions = parse_program(args[0], opts["--dialect"], spindle_check)
    if len(args) == 1:
        print("gcode_check: ok: %d motion lines in the %s word set, the spindle on before every feed"
              % (len(motions), opts["--dialect"]))
        return
    cl = [m for path in args[1:] for m in read_cl_csv(path, offset)]
    k = 0
    worst = 0.0  # --path-tol: the largest distance of a CL feed point from the posted path
    for kind, xyz, feed, first_of_file in cl:
        here = motions[k - 1][1] if k > 0 else None
        if here is not None and close(here, xyz, tol):
            continue  # a move shorter than the program's resolution needs no line
        if kind == "feed":
            while first_of_file and k < len(motions) and motions[k][0] == 0:
                k += 1  # the post's own approach from the safe plane
            if path_tol is not None:
                ends_next = k < len(motions) and motions[k][0] != 0 and close(motions[k][1], xyz, tol)
                if not ends_next and k > 0 and motions[k - 1][0] != 0:
                    d = distance_to_motion(xyz, motions[k - 1])
                    if d <= path_tol:
                        worst = max(worst, d)
                        continue  # inside the line or arc in progress
                if k >= len(motions):
                    fail("CL feed point %s is on no posted motion" % (xyz,))
                mode, pos, f, where = motions[k][:4]
                dist = distance_to_motion(xyz, motions[k])
                if mode == 0 or dist > path_tol or abs(f - feed) > 0.05:
                    fail("%s: CL feed point %s F%g is %.5f mm from this G%d (F%s), more than %g" % (where, xyz, feed, dist, mode, f, path_tol))
                worst = max(worst, dist)
                k += 1
                continue
            if k >= len(motions):
                fail("CL feed move to %s has no G1 line" % (xyz,))
            mode, pos, f, where = motions[k][:4]
            if mode != 1 or not close(pos, xyz, tol) or abs(f - feed) > 0.05:
                fail("%s: expected G1 to %s F%g (CL feed move), found G%d to %s F%s" % (where, xyz, feed, mode, pos, f))
            k += 1
        else:
            while True:
                if k >= len(motions):
                    fail("CL rapid to %s is never reached" % (xyz,))
                mode, pos, f, where = motions[k][:4]
                if mode != 0:
                    fail("%s: G%d while a CL rapid to %s was expected" % (where, mode, xyz))
                k += 1
                if close(pos, xyz, tol):
                    break
    last = motions[k - 1][1] if k > 0 else None
    for mode, pos, f, where, _, _ in motions[k:]:
        if mode != 0 or last is None or pos[0] != last[0] or pos[1] != last[1] or pos[2] < last[2]:
            fail("%s: motion after the last CL move that is not a retract straight up" % where)
        last = pos
    arcs = sum(1 for m in motions if m[0] in (2, 3))
    print("gcode_check: ok: %d CL moves matched by %d motion lines (%d arcs), %s word set%s"
          % (len(cl), len(motions), arcs, opts["--dialect"],
             "" if path_tol is None else ", CL points at most %.5f mm from the path" % worst))


if __name__ == "__main__":
    main()
