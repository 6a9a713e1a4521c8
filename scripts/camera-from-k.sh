#!/usr/bin/env bash
# A camera.yaml (docs/formats.md) from a 3 x 3 K written row by row in a text file (openMVG's
# K.txt; blanks or CRLF lines between the numbers), no distortion, for photos of WIDTH x HEIGHT.
#   scripts/camera-from-k.sh K.txt WIDTH HEIGHT > camera.yaml
set -euo pipefail
[ $# -eq 3 ] || { echo "usage: camera-from-k.sh K.txt WIDTH HEIGHT" >&2; exit 2; }
read -r fx _ cx _ fy cy _ < <(tr -s ' \r\n\t' ' ' < "$1"; echo)
[ -n "$cy" ] || { echo "camera-from-k.sh: $1: fewer than 6 numbers, not a 3 x 3 K" >&2; exit 1; }
cat <<YAML
%YAML:1.0
---
image_width: $2
image_height: $3
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ $fx, 0., $cx, 0., $fy, $cy, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 5
   cols: 1
   dt: d
   data: [ 0., 0., 0., 0., 0. ]
YAML
