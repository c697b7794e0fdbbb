#!/usr/bin/env bash
# How build time and rays per second grow with the primitive count: the sphereflake
# (balls) and tetra generators from ~1K to ~4M primitives, one thread, primary and
# diffuse sets, scalar and packet, with the fast and the exact builder. Writes
# perf/scaling/*.json and perf/scaling.png.
# Usage: perf/scaling.sh [REPEAT]   (from the repository root)
set -euo pipefail
cd "$(dirname "$0")/.."
repeat="${1:-3}"
cargo build --release
cargo build --release --features plot --bin raypack-plot
mkdir -p perf/scaling
for scene in spd:balls:3 spd:balls:4 spd:balls:5 spd:balls:6 \
             spd:tetra:4 spd:tetra:5 spd:tetra:6 spd:tetra:7 spd:tetra:8 spd:tetra:9 spd:tetra:10; do
    for builder in fast exact; do
        out="perf/scaling/${scene//:/_}_${builder}.json"
        RAYON_NUM_THREADS=1 target/release/raypack bench "$scene" --sets primary,diffuse \
            --modes scalar,packet --threads 1 --repeat "$repeat" --builder "$builder" \
            --json "$out"
    done
done
target/release/raypack-plot --out perf/scaling.png perf/scaling/*.json
