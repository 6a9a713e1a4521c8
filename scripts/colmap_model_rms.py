#!/usr/bin/env python3
"""Reprojection errors of a COLMAP text model, recomputed from its own cameras, poses and points.

  scripts/colmap_model_rms.py MODEL_DIR [--label NAME]

MODEL_DIR holds cameras.txt, images.txt and points3D.txt (COLMAP's text format, as `colmap
model_converter --output_type TXT` and `triangulate --colmap` write it). Each point's track
(IMAGE_ID, POINT2D_IDX pairs) is projected through its image's pose (cam_from_world: the
quaternion QW QX QY QZ and TX TY TZ of images.txt) and camera, and compared with the 2D point of
that index. One script for every model, so that two tools' figures are computed the same way
(their own reports use different measures: COLMAP prints a mean, photomill an RMS).

Camera models (COLMAP's src/base/camera_models.h conventions, written out here):
  SIMPLE_PINHOLE f cx cy; PINHOLE fx fy cx cy; SIMPLE_RADIAL f cx cy k; RADIAL f cx cy k1 k2;
  OPENCV fx fy cx cy k1 k2 p1 p2; FULL_OPENCV fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6.
With normalised coordinates u = X/Z, v = Y/Z and r2 = u^2 + v^2 the distorted point is
u' = u (1 + radial) + 2 p1 u v + p2 (r2 + 2 u^2), v' = v (1 + radial) + 2 p2 u v + p1 (r2 + 2 v^2),
radial = k1 r2 + k2 r2^2 (+ k3 r2^3 and the rational denominator 1 + k4 r2 + k5 r2^2 + k6 r2^3
for FULL_OPENCV), and the pixel is (fx u' + cx, fy v' + cy).

Prints one line: points, observations, mean track length, reprojection RMS, mean and median (px).
Standard library only.
"""
import math
import statistics
import sys

from quaternion import rotation


def project(model, p, u, v):
    """Pixel of the normalised point (u, v) through camera `model` with parameters p."""
    if model == "SIMPLE_PINHOLE":
        return p[0] * u + p[1], p[0] * v + p[2]
    if model == "PINHOLE":
        return p[0] * u + p[2], p[1] * v + p[3]
    r2 = u * u + v * v
    if model in ("SIMPLE_RADIAL", "RADIAL"):
        k1, k2 = p[3], (p[4] if model == "RADIAL" else 0.0)
        radial = 1 + k1 * r2 + k2 * r2 * r2
        return p[0] * u * radial + p[1], p[0] * v * radial + p[2]
    if model in ("OPENCV", "FULL_OPENCV"):
        fx, fy, cx, cy, k1, k2, p1, p2 = p[:8]
        radial = 1 + k1 * r2 + k2 * r2 * r2
        if model == "FULL_OPENCV":
            k3, k4, k5, k6 = p[8:12]
            radial = (radial + k3 * r2 ** 3) / (1 + k4 * r2 + k5 * r2 * r2 + k6 * r2 ** 3)
        ud = u * radial + 2 * p1 * u * v + p2 * (r2 + 2 * u * u)
        vd = v * radial + 2 * p2 * u * v + p1 * (r2 + 2 * v * v)
        return fx * ud + cx, fy * vd + cy
    sys.exit(f"colmap_model_rms: camera model {model} is not handled")


def lines(path):
    with open(path, encoding="utf-8") as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                yield line


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    folder = sys.argv[1]
    label = sys.argv[3] if len(sys.argv) > 3 and sys.argv[2] == "--label" else folder
    cameras = {}
    for line in lines(f"{folder}/cameras.txt"):
        f = line.split()
        cameras[int(f[0])] = (f[1], [float(x) for x in f[4:]])
    images = {}
    it = lines(f"{folder}/images.txt")
    for line in it:
        f = line.split()
        q = [float(x) for x in f[1:5]]
        t = [float(x) for x in f[5:8]]
        pts = next(it, "").split()
        xy = [(float(pts[k]), float(pts[k + 1])) for k in range(0, len(pts), 3)]
        images[int(f[0])] = (rotation(*q), t, cameras[int(f[8])], xy)
    errors = []
    points = 0
    for line in lines(f"{folder}/points3D.txt"):
        f = line.split()
        X = [float(x) for x in f[1:4]]
        track = f[8:]
        points += 1
        for k in range(0, len(track), 2):
            R, t, (model, params), xy = images[int(track[k])]
            c = [sum(R[r][j] * X[j] for j in range(3)) + t[r] for r in range(3)]
            if c[2] <= 0:
                errors.append(float("inf"))
                continue
            px, py = project(model, params, c[0] / c[2], c[1] / c[2])
            ox, oy = xy[int(track[k + 1])]
            errors.append(math.hypot(px - ox, py - oy))
    if not errors:
        sys.exit(f"colmap_model_rms: {folder}: no observations")
    rms = math.sqrt(sum(e * e for e in errors) / len(errors))
    print(f"{label}: {points} points, {len(errors)} observations, mean track length {len(errors) / points:.2f}, "
          f"reprojection RMS {rms:.4f} px, mean {statistics.fmean(errors):.4f} px, "
          f"median {statistics.median(errors):.4f} px")


if __name__ == "__main__":
    main()
