# FreeCAD side of scripts/bench-fitsurf-freecad.sh (issue #7): runs FreeCAD's ReverseEngineering
# approxSurface on a point cloud and samples the resulting B-spline surface - and, for the same
# sampling, the surface fitsurf wrote as STEP - into x y z files that fitsurf_bench --truth
# compares with the true surface. Run by freecadcmd (FreeCAD 0.20, Debian 12's freecad package),
# which takes no script arguments, so everything comes in environment variables:
#   FC_POINTS   input x y z text (the cloud both fitters get)
#   FC_OUT      samples of approxSurface's surface (x y z text)
#   FC_STEP     optional: fitsurf's STEP file, sampled into FC_STEP_OUT the same way
#   FC_NET      poles per direction (20), FC_DEGREE (3), FC_ITERATIONS (5, parameter correction
#               rounds), FC_SMOOTH (1/0), FC_WEIGHT (0.1), FC_GRAD (1.0), FC_BEND (0.0)
#   FC_SAMPLES  samples per parameter direction (200); FC_RESIDUALS points projected onto each
#               surface for the residual RMS (2000, every n-th point)
# approxSurface works in single precision in places: the points are centred on their mean first
# and the surface moved back afterwards (uncentred, parts 100 mm from the origin lose accuracy).
# Prints lines "RESULT key value" on stdout; FreeCAD's own chatter goes around them.
import os
import sys
import time

import FreeCAD
import Part
import ReverseEngineering


def env(name, default):
    return os.environ.get(name, default)


def read_xyz(path):
    pts = []
    with open(path) as f:
        for line in f:
            s = line.split()
            if len(s) >= 3 and not line.lstrip().startswith("#"):
                pts.append((float(s[0]), float(s[1]), float(s[2])))
    return pts


def sample(surf, n, path):
    u0, u1, v0, v1 = surf.bounds()
    with open(path, "w") as f:
        for i in range(n):
            u = u0 + (u1 - u0) * (i + 0.5) / n
            for j in range(n):
                v = v0 + (v1 - v0) * (j + 0.5) / n
                p = surf.value(u, v)
                f.write("%.9g %.9g %.9g\n" % (p.x, p.y, p.z))


def residual_rms(surf, pts, count):
    # Orthogonal distance of every n-th point: Open CASCADE's projection (GeomAPI_ProjectPointOnSurf).
    step = max(1, len(pts) // count)
    s2, mx, n = 0.0, 0.0, 0
    for k in range(0, len(pts), step):
        p = FreeCAD.Vector(*pts[k])
        u, v = surf.parameter(p)
        d = (surf.value(u, v) - p).Length
        s2 += d * d
        mx = max(mx, d)
        n += 1
    return (s2 / n) ** 0.5, mx, n


def main():
    pts = read_xyz(env("FC_POINTS", "points.xyz"))
    n = len(pts)
    cx = sum(p[0] for p in pts) / n
    cy = sum(p[1] for p in pts) / n
    cz = sum(p[2] for p in pts) / n
    centred = [(p[0] - cx, p[1] - cy, p[2] - cz) for p in pts]
    net = int(env("FC_NET", "20"))
    degree = int(env("FC_DEGREE", "3"))
    t0 = time.time()
    c0 = time.process_time()
    surf = ReverseEngineering.approxSurface(
        Points=centred, UDegree=degree, VDegree=degree, NbUPoles=net, NbVPoles=net,
        Smooth=env("FC_SMOOTH", "1") == "1", Weight=float(env("FC_WEIGHT", "0.1")),
        Grad=float(env("FC_GRAD", "1.0")), Bend=float(env("FC_BEND", "0.0")),
        Iterations=int(env("FC_ITERATIONS", "5")), Correction=True, PatchFactor=1.0)
    wall = time.time() - t0
    cpu = time.process_time() - c0
    surf.translate(FreeCAD.Vector(cx, cy, cz))
    samples = int(env("FC_SAMPLES", "200"))
    sample(surf, samples, env("FC_OUT", "freecad.xyz"))
    print("RESULT points %d" % n)
    print("RESULT freecad_poles %dx%d" % (surf.NbUPoles, surf.NbVPoles))
    print("RESULT freecad_degree %dx%d" % (surf.UDegree, surf.VDegree))
    print("RESULT freecad_wall_s %.2f" % wall)
    print("RESULT freecad_cpu_s %.2f" % cpu)
    count = int(env("FC_RESIDUALS", "2000"))
    rms, mx, m = residual_rms(surf, pts, count)
    print("RESULT freecad_residual_rms_mm %.5f" % rms)
    print("RESULT freecad_residual_max_mm %.5f" % mx)
    print("RESULT residual_points %d" % m)
    step = env("FC_STEP", "")
    if step:
        shape = Part.read(step)
        fs = shape.Faces[0].Surface
        sample(fs, samples, env("FC_STEP_OUT", "fitsurf.xyz"))
        print("RESULT fitsurf_step_poles %dx%d" % (fs.NbUPoles, fs.NbVPoles))
        rms, mx, m = residual_rms(fs, pts, count)
        print("RESULT fitsurf_residual_rms_mm %.5f" % rms)
        print("RESULT fitsurf_residual_max_mm %.5f" % mx)
    sys.stdout.flush()


main()
