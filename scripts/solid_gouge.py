# Checks a ball-end CL program against a STEP solid with Open CASCADE's exact B-rep distance
# (FreeCAD's Part.Shape.distToShape), independently of photomill's mesh: the ball centre at every
# CL point and at the midpoint of every feed move below the part's top + R; gouge = R - distance
# (R + distance where the centre is inside the solid). Run with freecadcmd:
#   STEP=part.step CL=part.cl R=3 freecadcmd scripts/solid_gouge.py
# Prints the number of centres and the deepest gouge with where.
import os
import time

import FreeCAD
import Part

step, cl, R = os.environ["STEP"], os.environ["CL"], float(os.environ.get("R", "3"))
shape = Part.read(step)
solid = shape.Solids[0] if shape.Solids else shape
top = shape.BoundBox.ZMax
centres, kind = [], None
for line in open(cl):
    if line.startswith("RAPID"):
        kind = "R"
    elif line.startswith("FEDRAT"):
        kind = "F"
    elif line.startswith("GOTO/"):
        x, y, z = map(float, line[5:].split(",")[:3])
        centres.append((kind, x, y, z + R))
points = []
for i, (k, x, y, z) in enumerate(centres):
    if z <= top + R:
        points.append((x, y, z))
    if i and k == "F":
        a = centres[i - 1]
        m = ((a[1] + x) / 2, (a[2] + y) / 2, (a[3] + z) / 2)
        if m[2] <= top + R:
            points.append(m)
start = time.time()
worst, at = -R, None
for (x, y, z) in points:
    p = FreeCAD.Vector(x, y, z)
    d = solid.distToShape(Part.Vertex(p))[0]
    g = R + d if solid.isInside(p, 1e-9, True) else R - d
    if g > worst:
        worst, at = g, (x, y, z)
print("solid_gouge: %d ball centres, deepest gouge %.6f mm at centre (%.3f, %.3f, %.3f), %.0f s"
      % (len(points), max(worst, 0.0), at[0], at[1], at[2], time.time() - start))
