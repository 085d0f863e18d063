#!/bin/sh
# Makes a real streamed SOG (PlayCanvas's lod-meta.json with one SOG folder per unit) for
# the docs' pictures. Level 0 is the scene itself; levels 1, 2 and 3 each keep half of the
# level before (splat-transform's --decimate 50%). The levels are cut into chunks of about
# 8K gaussians (--lod-chunk-count 8): a few dozen leaves for a scene of ~80K gaussians.
#
# Needs splat-transform 3.7.0 (the version the docs were made with), found by
# `npx --no-install splat-transform`: install it first with
#     npm install @playcanvas/splat-transform@3.7.0
# in this folder or a parent of it, or set SPLAT_TRANSFORM to the command to run
# (e.g. /path/to/node_modules/.bin/splat-transform). No GPU is needed (-g cpu).
#
# Usage: docs/lod_real_scene.sh SCENE OUT_FOLDER
#   SCENE: any scene splat-transform reads, e.g. ../shared/scenes/formats/pcwc-angel-kneeling.sog
#          (83,547 gaussians) or ../shared/scenes/donut-mip-fused.ply
#   OUT_FOLDER: made if absent; receives lod-meta.json, the unit folders ({level}_{i}/) and,
#          under levels/, the PLY of each level that the streamed scene was made from.
set -eu

if [ $# -ne 2 ]; then
    echo "usage: $0 SCENE OUT_FOLDER" >&2
    exit 2
fi
SCENE=$1
OUT=$2
ST=${SPLAT_TRANSFORM:-npx --no-install splat-transform}

VERSION=$($ST --version 2>&1 || true)  # it prints to stderr
case $VERSION in
    *v3.7.0*) ;;
    *) echo "$0: needs splat-transform 3.7.0 (found: '${VERSION:-none}'); see this script's header" >&2
       exit 1 ;;
esac

run() { $ST -q -g cpu -w "$@"; }

mkdir -p "$OUT/levels"
run "$SCENE" "$OUT/levels/level-0.ply"
for LEVEL in 1 2 3; do
    run "$OUT/levels/level-$((LEVEL - 1)).ply" --decimate 50% "$OUT/levels/level-$LEVEL.ply"
done
run --lod-chunk-count 8 \
    "$OUT/levels/level-0.ply" -l 0 "$OUT/levels/level-1.ply" -l 1 \
    "$OUT/levels/level-2.ply" -l 2 "$OUT/levels/level-3.ply" -l 3 \
    "$OUT/lod-meta.json"
echo "wrote $OUT/lod-meta.json"
