#!/usr/bin/env python3
"""Camera-centre errors of estimated poses against true poses.

  scripts/compare-poses.py TRUTH.csv ESTIMATE [--similarity]

TRUTH.csv is a photomill poses CSV (image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm; cam_from_world).
ESTIMATE is a photomill poses CSV or a COLMAP text model's images.txt (also cam_from_world,
"IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME" then a line of 2D points). Images are matched by
file name without folders. The camera centre is C = -R^T t.

--similarity first maps the estimated centres onto the true ones by the least-squares similarity
(rotation, translation, scale): B. K. P. Horn, "Closed-form solution of absolute orientation
using unit quaternions", JOSA A 4(4), 1987 -- the rotation is the unit eigenvector of the largest
eigenvalue of the 4x4 matrix N built from the cross-covariance of the centred point sets (found
here by power iteration on N + c I, c > |N|), and the scale is the ratio of the point spreads
(Horn's symmetric form, section 2.E). Without it the estimate must already be in the truth's
frame (control points).

Prints one line: cameras, RMS and max centre error in mm. Standard library only.
"""
import csv
import math
import sys

from quaternion import rotation


def centre(q, t):
    R = rotation(*q)
    return [-(R[0][i] * t[0] + R[1][i] * t[1] + R[2][i] * t[2]) for i in range(3)]


def load(path):
    out = {}
    if path.endswith(".csv"):
        with open(path, newline="") as f:
            for r in csv.DictReader(ln for ln in f if not ln.startswith("#")):  # a stamp, comments
                q = [float(r[k]) for k in ("qw", "qx", "qy", "qz")]
                t = [float(r[k]) for k in ("tx_mm", "ty_mm", "tz_mm")]
                out[r["image"].replace("\\", "/").split("/")[-1]] = centre(q, t)
        return out
    with open(path) as f:  # COLMAP images.txt
        lines = [ln for ln in f if not ln.startswith("#")]
    for ln in lines[0::2]:
        v = ln.split()
        if len(v) < 10:
            continue
        out[v[9].split("/")[-1]] = centre([float(a) for a in v[1:5]], [float(a) for a in v[5:8]])
    return out


def similarity(src, dst):
    """Horn (1987): s, R, t minimising sum |dst - (s R src + t)|^2."""
    n = len(src)
    ms = [sum(p[i] for p in src) / n for i in range(3)]
    md = [sum(p[i] for p in dst) / n for i in range(3)]
    a = [[p[i] - ms[i] for i in range(3)] for p in src]
    b = [[p[i] - md[i] for i in range(3)] for p in dst]
    S = [[sum(a[k][i] * b[k][j] for k in range(n)) for j in range(3)] for i in range(3)]
    (xx, xy, xz), (yx, yy, yz), (zx, zy, zz) = S
    N = [[xx + yy + zz, yz - zy, zx - xz, xy - yx],
         [yz - zy, xx - yy - zz, xy + yx, zx + xz],
         [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
         [xy - yx, zx + xz, yz + zy, -xx - yy + zz]]
    c = sum(abs(v) for row in N for v in row) + 1.0
    q = [1.0, 0.0, 0.0, 0.0]
    for _ in range(100000):
        nq = [sum(N[i][j] * q[j] for j in range(4)) + c * q[i] for i in range(4)]
        norm = math.sqrt(sum(v * v for v in nq))
        nq = [v / norm for v in nq]
        done = sum((nq[i] - q[i]) ** 2 for i in range(4)) < 1e-30
        q = nq
        if done:
            break
    R = rotation(*q)
    s = math.sqrt(sum(v * v for p in b for v in p) / sum(v * v for p in a for v in p))
    Rms = [sum(R[i][j] * ms[j] for j in range(3)) for i in range(3)]
    t = [md[i] - s * Rms[i] for i in range(3)]
    return lambda p: [s * sum(R[i][j] * p[j] for j in range(3)) + t[i] for i in range(3)]


def main():
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    if len(args) != 2:
        sys.exit(__doc__)
    truth, est = load(args[0]), load(args[1])
    names = sorted(set(truth) & set(est))
    if len(names) < 3:
        sys.exit("compare-poses: fewer than 3 images in common")
    if "--similarity" in sys.argv:
        f = similarity([est[k] for k in names], [truth[k] for k in names])
        est = {k: f(est[k]) for k in names}
    errs = [math.dist(est[k], truth[k]) for k in names]
    print("cameras %d of %d  centre error RMS %.4f mm  max %.4f mm%s" % (
        len(names), len(truth), math.sqrt(sum(e * e for e in errs) / len(errs)), max(errs),
        "  (after a similarity)" if "--similarity" in sys.argv else ""))


if __name__ == "__main__":
    main()
