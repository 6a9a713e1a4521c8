# FreeCAD side of scripts/bench-rough.sh (issue 26): FreeCAD 0.20's Path Adaptive clearing the
# same stock as photomill's `rough`, with the same flat end mill, and the G-code it makes turned
# into photomill CL CSV so that both programs are measured by the same code.
#
# Run by freecadcmd (Debian 12's freecad, 0.20.2), which takes no script arguments, so everything
# comes in environment variables:
#   FC_STEP       the surface as a STEP B-spline face (one face, or a shell of faces)
#   FC_STOCK      stock box X0,Y0,Z0,X1,Y1,Z1 in mm (rough's, from its stderr)
#   FC_OUT        output prefix: FC_OUT.ngc (LinuxCNC post), FC_OUT.csv (CL CSV), FC_OUT.json
#   FC_TOOL_D     flat end mill diameter (6)
#   FC_STEP_DOWN  depth between levels (2)
#   FC_STEP_OVER  Adaptive's step-over, percent of the diameter (40)
#   FC_ALLOWANCE  material left on the surface (0.5), vertically as in rough (see below)
#   FC_STOCK_TO_LEAVE  Adaptive's own StockToLeave, horizontal (0: the allowance is already in
#                 the level's island, below)
#   FC_ISLAND_ALLOWANCE  the island is the section at z - this (default FC_ALLOWANCE); 0 with
#                 FC_STOCK_TO_LEAVE=0.5 is the literal reading of "stock to leave 0.5": the
#                 allowance only sideways, none under the tool
#   FC_FEED, FC_PLUNGE_FEED   1000, 300 mm/min (tool controller's HorizFeed, VertFeed)
#   FC_HELIX_ANGLE  helix ramp angle, degrees (3, as rough's --ramp-angle-deg)
#   FC_TOLERANCE  Adaptive's Tolerance (0.1, its default)
#   FC_RETRACT    clearance height above the stock top (5, as rough's --retract-mm)
#
# What Adaptive is in FreeCAD 0.20 (PathScripts/PathAdaptive.py): a 2D clearing (libarea's
# Adaptive2d) of the region between the stock's outline and the outline of the selected
# horizontal faces, repeated unchanged at every step-down from StartDepth to FinalDepth. It does
# not look at the 3D model below the faces; no 0.20 operation clears a free-form part by levels
# without OpenCamLib (3D Surface and Waterline need it, and Debian has no python3 ocl). So a
# single Adaptive on this part could only clear the stock outside the part's silhouette, which is
# the surface's whole xy box. What this script does instead is what a user would do by hand:
# one Adaptive operation per level z_k (the same levels as rough: the stock top minus k step-downs,
# the last at the stock bottom + allowance), Side Outside, whose faces are the part's horizontal
# section at z_k - allowance (the island: where the surface is within the allowance of the tool
# tip or above it), cut from the previous level (StartDepth) down to z_k (FinalDepth) with
# the helix entry. Adaptive keeps the tool's radius (plus StockToLeave) off the island, so the
# centre stays where every surface point under the tool is at least the allowance below the tip:
# the same free region as rough's step 4 (T <= z), up to Adaptive's tolerance.
#
# The G-code is written by FreeCAD's LinuxCNC post (linuxcnc_post.py, 4 decimals) and read back
# here (gcode_to_cl: G0/G1/G2/G3 with I J, arcs into chords within FC_CHORD, 0.001 mm).
# Also usable without FreeCAD: `python3 freecad_adaptive.py gcode2cl IN.ngc OUT.csv`.
# Prints lines "RESULT key value" on stdout; FreeCAD's chatter goes around them.
import json
import math
import os
import re
import sys
import time


def env(name, default):
    return os.environ.get(name, default)


# --- G-code to CL CSV (plain Python) ---------------------------------------------------------

WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")


def gcode_to_cl(lines, chord_tol=0.001):
    """Moves of a G-code program (G90, G17, G21, G0/G1/G2/G3, I J incremental centres, F mm/min)
    as (kind, x, y, z, feed) tuples; arcs become chords whose sagitta is at most chord_tol. The
    moves before x, y and z are all known (a first G0 Z) are folded into the first full position."""
    moves = []
    pos = [None, None, None]
    motion = None
    feed = 0.0
    for raw in lines:
        line = re.sub(r"\([^)]*\)", "", raw.split(";", 1)[0]).strip()
        if not line:
            continue
        words = [(w.upper(), float(v)) for w, v in WORD.findall(line)]
        gs = [v for w, v in words if w == "G"]
        for g in gs:
            if g in (0, 1, 2, 3):
                motion = int(g)
            elif g in (20, 91):
                raise ValueError("unsupported G%g (inches or incremental): %s" % (g, raw.strip()))
        vals = {w: v for w, v in words if w in "XYZIJF"}
        if "F" in vals:
            feed = vals["F"]
        if not any(a in vals for a in "XYZ"):
            continue
        if motion is None:
            raise ValueError("axis words before any G0/G1/G2/G3: %s" % raw.strip())
        start = list(pos)
        end = [vals.get(a, p) for a, p in zip("XYZ", pos)]
        pos = end
        if None in end:
            continue
        if None in start:
            # the first full position: where the program starts
            moves.append(("rapid", end[0], end[1], end[2], 0.0))
            continue
        if motion == 0:
            moves.append(("rapid", end[0], end[1], end[2], 0.0))
            continue
        if feed <= 0:
            raise ValueError("feed move without a feed rate: %s" % raw.strip())
        if motion == 1:
            moves.append(("feed", end[0], end[1], end[2], feed))
            continue
        cx = start[0] + vals.get("I", 0.0)
        cy = start[1] + vals.get("J", 0.0)
        r = math.hypot(start[0] - cx, start[1] - cy)
        a0 = math.atan2(start[1] - cy, start[0] - cx)
        a1 = math.atan2(end[1] - cy, end[0] - cx)
        sweep = a1 - a0
        if motion == 3:  # counter-clockwise
            while sweep <= 1e-12:
                sweep += 2 * math.pi
        else:
            while sweep >= -1e-12:
                sweep -= 2 * math.pi
        if r <= chord_tol:
            n = 1
        else:
            n = max(1, math.ceil(abs(sweep) / (2 * math.acos(1 - chord_tol / r))))
        for k in range(1, n):
            a = a0 + sweep * k / n
            moves.append(("feed", cx + r * math.cos(a), cy + r * math.sin(a),
                          start[2] + (end[2] - start[2]) * k / n, feed))
        moves.append(("feed", end[0], end[1], end[2], feed))
    return moves


def write_cl_csv(moves, path):
    with open(path, "w") as f:
        f.write("move,x_mm,y_mm,z_mm,i,j,k,feed_mm_per_min\n")
        for kind, x, y, z, fd in moves:
            if kind == "rapid":
                f.write("rapid,%.6f,%.6f,%.6f,,,,\n" % (x, y, z))
            else:
                f.write("feed,%.6f,%.6f,%.6f,,,,%g\n" % (x, y, z, fd))


# --- FreeCAD ---------------------------------------------------------------------------------

def run_freecad():
    import FreeCAD
    import Part
    from PathScripts import PathAdaptive, PathJob, PathStock, PathToolBit, PathToolController
    from PathScripts.post import linuxcnc_post

    V = FreeCAD.Vector
    t_start = time.time()
    step_path = env("FC_STEP", "")
    out = env("FC_OUT", "adaptive")
    x0, y0, z0, x1, y1, z1 = [float(v) for v in env("FC_STOCK", "").split(",")]
    tool_d = float(env("FC_TOOL_D", "6"))
    step_down = float(env("FC_STEP_DOWN", "2"))
    step_over = float(env("FC_STEP_OVER", "40"))
    allowance = float(env("FC_ALLOWANCE", "0.5"))
    stock_to_leave = float(env("FC_STOCK_TO_LEAVE", "0"))
    island_allowance = float(env("FC_ISLAND_ALLOWANCE", str(allowance)))
    feed = float(env("FC_FEED", "1000"))
    plunge = float(env("FC_PLUNGE_FEED", "300"))
    helix_angle = float(env("FC_HELIX_ANGLE", "3"))
    tolerance = float(env("FC_TOLERANCE", "0.1"))
    retract = float(env("FC_RETRACT", "5"))
    chord = float(env("FC_CHORD", "0.001"))

    doc = FreeCAD.newDocument("bench_rough")
    shape = Part.read(step_path)
    faces = shape.Faces
    if not faces:
        raise SystemExit("no face in " + step_path)
    # The part: the surface swept down below the stock, cut at the stock bottom (a height field
    # over the face's xy domain; off the face the part is the stock bottom, as in rough).
    depth = (z1 - z0) + 50
    below = Part.makeBox(x1 - x0 + 20, y1 - y0 + 20, z1 - z0 + 50, V(x0 - 10, y0 - 10, z0))
    sweeps = [f.extrude(V(0, 0, -depth)) for f in faces]
    solid = sweeps[0]
    for s in sweeps[1:]:
        solid = solid.fuse(s)
    solid = solid.common(below)
    part = doc.addObject("Part::Feature", "Part")
    part.Shape = solid
    t_model = time.time()

    job = PathJob.Create("Job", [part], None)
    # the same stock box as rough
    old = job.Stock
    job.Stock = PathStock.CreateBox(job, V(x1 - x0, y1 - y0, z1 - z0),
                                    FreeCAD.Placement(V(x0, y0, z0), FreeCAD.Rotation()))
    if old:
        doc.removeObject(old.Name)
    shape_file = "/usr/share/freecad/Mod/Path/Tools/Shape/endmill.fcstd"
    bit = PathToolBit.Factory.Create("EndMill6", shape_file)
    bit.Diameter = tool_d
    bit.CuttingEdgeHeight = (z1 - z0) + 10
    bit.Length = (z1 - z0) + 30
    for tc in list(job.Tools.Group):
        job.Tools.removeObject(tc)
        doc.removeObject(tc.Name)
    tc = PathToolController.Create("TC_EndMill6", bit, 1)
    tc.HorizFeed = "%g mm/min" % feed
    tc.VertFeed = "%g mm/min" % plunge
    tc.SpindleSpeed = 12000
    job.Proxy.addToolController(tc)

    # rough's levels: the stock top minus k step-downs, the last at the lowest tool tip
    last = z0 + allowance
    levels = []
    k = 1
    while z1 - k * step_down > last + 1e-9:
        levels.append(z1 - k * step_down)
        k += 1
    levels.append(last)

    clearance = z1 + retract
    ops = []
    empty_levels = 0
    prev = z1
    for i, z in enumerate(levels):
        zs = z - island_allowance + 1e-3  # 1 um: a surface exactly at the allowance does not block
        wires = solid.slice(V(0, 0, 1), zs)
        island = None
        if wires:
            island = Part.makeFace(wires, "Part::FaceMakerBullseye")
        op = PathAdaptive.Create("Adaptive%02d" % (i + 1))
        job.Proxy.addOperation(op)
        op.ToolController = tc
        if island is not None and island.Faces:
            feat = doc.addObject("Part::Feature", "Island%02d" % (i + 1))
            feat.Shape = island
            op.Base = [(feat, ["Face%d" % (j + 1) for j in range(len(island.Faces))])]
            op.Side = "Outside"
        else:
            # nothing of the part at this level: clear the whole stock
            empty_levels += 1
            face = Part.makePlane(x1 - x0, y1 - y0, V(x0, y0, zs))
            feat = doc.addObject("Part::Feature", "StockFace%02d" % (i + 1))
            feat.Shape = face
            op.Base = [(feat, ["Face1"])]
            op.Side = "Inside"
        op.OperationType = "Clearing"
        for prop in ("StartDepth", "FinalDepth", "StepDown", "SafeHeight", "ClearanceHeight",
                     "FinishDepth"):
            op.setExpression(prop, None)
        op.StartDepth = prev
        op.FinalDepth = z
        op.StepDown = max(step_down, prev - z)  # one pass per operation
        op.FinishDepth = 0
        op.SafeHeight = prev + 1.0  # rough's --clearance-mm: 1 mm above the material
        op.ClearanceHeight = clearance
        op.StepOver = int(round(step_over))  # App::PropertyPercent
        op.StockToLeave = stock_to_leave
        op.Tolerance = tolerance
        op.HelixAngle = helix_angle
        op.HelixConeAngle = 0
        op.UseHelixArcs = False
        op.FinishingProfile = True
        op.ForceInsideOut = False
        op.LiftDistance = 0
        op.KeepToolDownRatio = 3.0
        ops.append(op)
        prev = z
    t_setup = time.time()

    doc.recompute()
    t_ops = time.time()

    regions = helices = 0
    for o in ops:
        for reg in (o.AdaptiveOutputState or []):
            regions += 1
            c, p = reg["HelixCenterPoint"], reg["StartPoint"]
            if math.hypot(c[0] - p[0], c[1] - p[1]) > 0.01:
                helices += 1
    errors = [o.Label for o in ops if not o.Path.Commands or len(o.Path.Commands) < 3]
    ngc = out + ".ngc"
    linuxcnc_post.export([tc] + ops, ngc,
                         "--no-show-editor --precision=4 --no-comments --no-header")
    t_post = time.time()
    with open(ngc) as f:
        moves = gcode_to_cl(f, chord)
    write_cl_csv(moves, out + ".csv")
    t_end = time.time()

    result = {
        "freecad_version": ".".join(FreeCAD.Version()[:3]),
        "levels": len(levels),
        "first_level": levels[0],
        "last_level": levels[-1],
        "empty_levels": empty_levels,
        "regions": regions,
        "helix_entries": helices,
        "ops_without_path": errors,
        "gcode_lines": sum(1 for _ in open(ngc)),
        "gcode_motion_lines": sum(1 for l in open(ngc) if re.match(r"^(N\d+ )?G[0123]\b", l)),
        "cl_moves": len(moves),
        "model_s": t_model - t_start,
        "setup_s": t_setup - t_model,
        "adaptive_s": t_ops - t_setup,
        "post_s": t_post - t_ops,
        "convert_s": t_end - t_post,
        "total_s": t_end - t_start,
    }
    with open(out + ".json", "w") as f:
        json.dump(result, f, indent=1)
    for k, v in result.items():
        print("RESULT %s %s" % (k, v))


if __name__ == "__main__" and len(sys.argv) >= 4 and sys.argv[1] == "gcode2cl":
    with open(sys.argv[2]) as f:
        write_cl_csv(gcode_to_cl(f, float(env("FC_CHORD", "0.001"))), sys.argv[3])
elif "FC_STEP" in os.environ:
    try:
        run_freecad()
    except Exception:
        import traceback
        traceback.print_exc()
        print("RESULT error %s" % repr(sys.exc_info()[1]))
        raise
