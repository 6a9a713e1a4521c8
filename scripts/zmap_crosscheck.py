#!/usr/bin/env python3
# A rough z-map CROSS-CHECK for scripts/bench-rough.sh, not photomill's stock simulator (that is
# cutsim): cuts a stock box with a flat end mill along CL CSV programs on a z-map and reports what
# is left over the surface. Python + numpy, approximate:
# - the surface's height at a cell is the sample nearest the cell's centre among the surface
#   sampled on a uniform (u, v) grid about 3 times finer than the cells (error about the slope
#   times a third of a cell);
# - each CL move (rapids too) lowers every cell whose centre is within the tool radius of the
#   move's xy segment to the lowest tool tip z over that part of the move (a flat end mill's
#   swept bottom, exact for straight moves);
# - statistics over the cells inside the stock whose centre lies on the surface's xy footprint:
#   material left above surface + allowance (p95, max), deepest cut into the allowance and below
#   the surface (vertical).
#   zmap_crosscheck.py SURFACE.txt STOCK(X0,Y0,Z0,X1,Y1,Z1) TOOL_D ALLOWANCE CELL CL.csv...
import math
import sys

import numpy as np


def read_surface(path):
    """photomill-surface v1, non-rational (docs/formats.md)."""
    deg = poles = None
    ku = kv = None
    P = None
    with open(path) as f:
        for line in f:
            s = line.split()
            if not s or s[0].startswith("#"):
                continue
            if s[0] == "degrees":
                deg = (int(s[1]), int(s[2]))
            elif s[0] == "poles":
                poles = (int(s[1]), int(s[2]))
                P = np.zeros((poles[0], poles[1], 3))
            elif s[0] == "rational" and s[1] != "0":
                raise SystemExit("rational surfaces are not handled by this cross-check")
            elif s[0] == "knots_u":
                ku = np.array([float(v) for v in s[1:]])
            elif s[0] == "knots_v":
                kv = np.array([float(v) for v in s[1:]])
            elif s[0] == "pole":
                P[int(s[1]), int(s[2])] = [float(v) for v in s[3:6]]
    return deg, ku, kv, P


def basis(knots, p, n, t):
    """B-spline basis values (len(t) x n) by Cox-de Boor, t in [knots[p], knots[n]]."""
    t = np.clip(t, knots[p], knots[n] - 1e-12)
    N = np.zeros((len(t), len(knots) - 1))
    for i in range(len(knots) - 1):
        N[:, i] = (knots[i] <= t) & (t < knots[i + 1])
    for d in range(1, p + 1):
        M = np.zeros((len(t), len(knots) - 1 - d))
        for i in range(len(knots) - 1 - d):
            a = knots[i + d] - knots[i]
            b = knots[i + d + 1] - knots[i + 1]
            if a > 0:
                M[:, i] += (t - knots[i]) / a * N[:, i]
            if b > 0:
                M[:, i] += (knots[i + d + 1] - t) / b * N[:, i + 1]
        N = M
    return N[:, :n]


def surface_heights(path, x0, y0, nx, ny, cell):
    (pu, pv), ku, kv, P = read_surface(path)
    nu, nv = P.shape[0], P.shape[1]
    ext = P.reshape(-1, 3).max(0) - P.reshape(-1, 3).min(0)
    su = int(math.ceil(3 * ext[0] / cell)) + 1
    sv = int(math.ceil(3 * ext[1] / cell)) + 1
    Bu = basis(ku, pu, nu, np.linspace(ku[pu], ku[nu], su))
    Bv = basis(kv, pv, nv, np.linspace(kv[pv], kv[nv], sv))
    S = np.stack([Bu @ P[:, :, c] @ Bv.T for c in range(3)], axis=-1).reshape(-1, 3)
    ix = np.floor((S[:, 0] - x0) / cell).astype(int)
    iy = np.floor((S[:, 1] - y0) / cell).astype(int)
    ok = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
    S, ix, iy = S[ok], ix[ok], iy[ok]
    d = np.hypot(S[:, 0] - (x0 + (ix + 0.5) * cell), S[:, 1] - (y0 + (iy + 0.5) * cell))
    order = np.argsort(-d)  # nearest last: it wins the assignment
    H = np.full((ny, nx), np.nan)
    H[iy[order], ix[order]] = S[order, 2]
    # a cell is on the surface when a sample within half a cell of its centre exists
    near = np.zeros((ny, nx), bool)
    near[iy[d <= 0.5 * cell], ix[d <= 0.5 * cell]] = True
    H[~near] = np.nan
    return H


def read_cl(path):
    with open(path) as f:  # photomill's CL CSV: a stamp comment, the column header, the moves
        lines = [ln for ln in f if ln.strip() and not ln.startswith("#")][1:]
    rows = np.genfromtxt(lines, delimiter=",", usecols=(1, 2, 3))
    return rows.reshape(-1, 3)


def pieces(pts, longest):
    """The moves split into pieces no longer than `longest` in xy (small windows, same cut)."""
    for a, b in zip(pts[:-1], pts[1:]):
        n = max(1, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / longest)))
        for k in range(n):
            yield a + (b - a) * (k / n), a + (b - a) * ((k + 1) / n)


def cut(Z, x0, y0, cell, R, pts):
    ny, nx = Z.shape
    r2 = R * R
    for a, b in pieces(pts, 2 * R):
        lo = np.minimum(a[:2], b[:2]) - R
        hi = np.maximum(a[:2], b[:2]) + R
        i0 = max(int((lo[0] - x0) / cell), 0)
        i1 = min(int((hi[0] - x0) / cell) + 1, nx)
        j0 = max(int((lo[1] - y0) / cell), 0)
        j1 = min(int((hi[1] - y0) / cell) + 1, ny)
        if i0 >= i1 or j0 >= j1:
            continue
        if min(a[2], b[2]) >= Z[j0:j1, i0:i1].max():
            continue
        cx = x0 + (np.arange(i0, i1) + 0.5) * cell
        cy = y0 + (np.arange(j0, j1) + 0.5) * cell
        px, py = np.meshgrid(cx - a[0], cy - a[1])
        dx, dy = b[0] - a[0], b[1] - a[1]
        L2 = dx * dx + dy * dy
        if L2 < 1e-18:
            inside = px * px + py * py <= r2
            zc = np.where(inside, min(a[2], b[2]), np.inf)
        else:
            # |p - a - t d|^2 <= R^2: t in [tc - h, tc + h]
            tc = (px * dx + py * dy) / L2
            q = (px * px + py * py) - tc * tc * L2
            disc = (r2 - q) / L2
            h = np.sqrt(np.maximum(disc, 0))
            inside = (disc >= 0) & (tc + h >= 0) & (tc - h <= 1)
            t_lo = np.clip(tc - h, 0, 1)
            t_hi = np.clip(tc + h, 0, 1)
            zl = a[2] + (b[2] - a[2]) * t_lo
            zh = a[2] + (b[2] - a[2]) * t_hi
            zc = np.where(inside, np.minimum(zl, zh), np.inf)
        np.minimum(Z[j0:j1, i0:i1], zc, out=Z[j0:j1, i0:i1])


def main():
    surf = sys.argv[1]
    x0, y0, z0, x1, y1, z1 = [float(v) for v in sys.argv[2].split(",")]
    R = float(sys.argv[3]) / 2
    allowance = float(sys.argv[4])
    cell = float(sys.argv[5])
    nx = int(math.ceil((x1 - x0) / cell))
    ny = int(math.ceil((y1 - y0) / cell))
    H = surface_heights(surf, x0, y0, nx, ny, cell)
    on = ~np.isnan(H)
    print("cross-check z-map: %d x %d cells of %.2f mm, %d on the surface" % (nx, ny, cell, on.sum()))
    print("| program | left p95 mm | left max mm | into allowance mm | below surface mm |")
    print("|---|---|---|---|---|")
    for path in sys.argv[6:]:
        Z = np.full((ny, nx), z1)
        cut(Z, x0, y0, cell, R, read_cl(path))
        left = (Z - (H + allowance))[on]
        into = max(0.0, float((H + allowance - Z)[on].max()))
        below = max(0.0, float((H - Z)[on].max()))
        print("| %s | %.3f | %.3f | %.3f | %.3f |" % (
            path, np.percentile(left, 95), left.max(), into, below))


if __name__ == "__main__":
    main()
