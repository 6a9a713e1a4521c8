#!/usr/bin/env python3
"""Compares two feature files of one photo (photomill-features v1, docs/formats.md), e.g. one
detect build's against another's: pairs their keypoints (x, y and size within --tolerance-px,
angle within --tolerance-deg) and prints how many pair, the largest position difference, the
largest relative response difference and how many descriptor bytes differ (and by how much).
Usage: scripts/feat_diff.py A.feat B.feat [--tolerance-px 0.001] [--tolerance-deg 0.01]
Exit 1 if the files do not hold the same number of keypoints or some keypoint has no pair."""
import argparse
import bisect
import sys


def load(path):
    rows = []
    with open(path) as f:
        for line in f:
            if line[:1].isdigit() or line[:1] == '-':
                v = line.split()
                rows.append((float(v[0]), float(v[1]), float(v[2]), float(v[3]), float(v[4]), [int(x) for x in v[5:]]))
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('a')
    ap.add_argument('b')
    ap.add_argument('--tolerance-px', type=float, default=1e-3)
    ap.add_argument('--tolerance-deg', type=float, default=1e-2)
    o = ap.parse_args()
    a, b = load(o.a), load(o.b)
    b.sort(key=lambda r: r[0])
    xs = [r[0] for r in b]
    used = [False] * len(b)
    paired = 0
    max_pos = max_resp = 0.0
    bytes_total = bytes_diff = max_byte = 0
    for r in a:
        i = bisect.bisect_left(xs, r[0] - o.tolerance_px)
        while i < len(b) and xs[i] <= r[0] + o.tolerance_px:
            s = b[i]
            turn = abs((s[3] - r[3] + 180) % 360 - 180)
            if not used[i] and abs(s[1] - r[1]) <= o.tolerance_px and abs(s[2] - r[2]) <= o.tolerance_px and turn <= o.tolerance_deg:
                used[i] = True
                paired += 1
                max_pos = max(max_pos, abs(s[0] - r[0]), abs(s[1] - r[1]))
                if r[4] != 0:
                    max_resp = max(max_resp, abs(s[4] - r[4]) / abs(r[4]))
                d = [abs(x - y) for x, y in zip(r[5], s[5])]
                bytes_total += len(d)
                bytes_diff += sum(1 for v in d if v)
                max_byte = max([max_byte] + d)
                break
            i += 1
    print('%d and %d keypoints, %d paired; position within %.2g px, response within %.2g relative; '
          'descriptor bytes differing %d of %d, by up to %d' % (len(a), len(b), paired, max_pos, max_resp,
                                                                bytes_diff, bytes_total, max_byte))
    return 0 if len(a) == len(b) == paired else 1


if __name__ == '__main__':
    sys.exit(main())
