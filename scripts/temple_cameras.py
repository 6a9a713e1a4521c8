#!/usr/bin/env python3
# The Middlebury temple's true cameras (templeSR_par.txt: K, R, t per image, metres) as
# photomill's camera.yaml and poses CSV (cam_from_world, mm) in OUT_DIR.
# Usage: temple_cameras.py templeSR_par.txt OUT_DIR
import math, sys
rows = [l.split() for l in open(sys.argv[1]).read().split('\n')[1:] if l.strip()]
def quat(R):
    t = R[0][0] + R[1][1] + R[2][2]
    if t > 0:
        s = math.sqrt(t + 1) * 2; q = [s / 4, (R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s]
    elif R[0][0] > R[1][1] and R[0][0] > R[2][2]:
        s = math.sqrt(1 + R[0][0] - R[1][1] - R[2][2]) * 2; q = [(R[2][1] - R[1][2]) / s, s / 4, (R[0][1] + R[1][0]) / s, (R[0][2] + R[2][0]) / s]
    elif R[1][1] > R[2][2]:
        s = math.sqrt(1 + R[1][1] - R[0][0] - R[2][2]) * 2; q = [(R[0][2] - R[2][0]) / s, (R[0][1] + R[1][0]) / s, s / 4, (R[1][2] + R[2][1]) / s]
    else:
        s = math.sqrt(1 + R[2][2] - R[0][0] - R[1][1]) * 2; q = [(R[1][0] - R[0][1]) / s, (R[0][2] + R[2][0]) / s, (R[1][2] + R[2][1]) / s, s / 4]
    n = math.sqrt(sum(v * v for v in q))
    return [v / n for v in q]
with open(sys.argv[2] + '/poses.csv', 'w') as f:
    f.write('image,qw,qx,qy,qz,tx_mm,ty_mm,tz_mm\n')
    for r in rows:
        v = list(map(float, r[10:19]))
        q = quat([v[0:3], v[3:6], v[6:9]])
        f.write(','.join([r[0]] + ['%.17g' % a for a in q] + ['%.17g' % (float(a) * 1000) for a in r[19:22]]) + '\n')
k = list(map(float, rows[0][1:10]))
open(sys.argv[2] + '/camera.yaml', 'w').write(
    '%%YAML:1.0\n---\nimage_width: 640\nimage_height: 480\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n'
    '   dt: d\n   data: [ %r, 0., %r, 0., %r, %r, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n'
    '   rows: 5\n   cols: 1\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n' % (k[0], k[2], k[4], k[5]))
