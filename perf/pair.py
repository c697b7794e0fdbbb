#!/usr/bin/env python3
"""Two raypack binaries (or one under two environments) on the same rays, in turn.

Runs `bench SCENE --modes MODES --threads 1` with binary A, then B, then A, ... for
`--rounds` rounds per scene, and prints per scene, ray set and mode the median over the
rounds of B's Mrays/s over A's in the same round, with both medians and whether the
checksums agree. Pairing within a round keeps the load of the machine out of the ratio.

    # a default build against one made for the CPU (perf/isa.md)
    RUSTFLAGS="-C target-cpu=native" cargo build --release --target-dir target/native
    python3 perf/pair.py target/native/release/raypack target/release/raypack

    # the AVX2 kernels against the baseline ones, one binary
    python3 perf/pair.py target/release/raypack target/release/raypack \\
        --env-a RAYPACK_ISA=sse
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def bench(binary, env, scene, args, out):
    label, _, arg = scene.partition("=")
    cmd = [binary, "bench", arg or label, "--modes", args.modes, "--sets", args.sets,
           "--threads", "1", "--repeat", str(args.repeat), "--accel", args.accel, "--json", out]
    if args.rays:
        cmd += ["--rays", os.path.join(args.rays, label)]
    full_env = dict(os.environ)
    full_env.update(env)
    subprocess.run(cmd, check=True, env=full_env, stdout=subprocess.DEVNULL)
    with open(out) as f:
        rows = json.load(f)["results"]
    return {(r["set"], r["mode"]): (r["mrays_median"], r["checksum"]) for r in rows}


def parse_env(items):
    env = {}
    for item in items or []:
        key, _, value = item.partition("=")
        env[key] = value
    return env


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("a", help="binary A (the reference)")
    ap.add_argument("b", help="binary B")
    ap.add_argument("--env-a", action="append", help="KEY=VALUE for A's runs")
    ap.add_argument("--env-b", action="append", help="KEY=VALUE for B's runs")
    ap.add_argument("--scenes", default="bunny,conference,sponza",
                    help="raypack's scene arguments, comma-separated; NAME=ARG labels a "
                         "scene given by path (its rays in --rays/NAME)")
    ap.add_argument("--sets", default="primary,shadow,diffuse")
    ap.add_argument("--modes", default="all")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--repeat", type=int, default=5, help="passes per bench run")
    ap.add_argument("--rays", help="folder of ray sets, one subfolder per scene")
    ap.add_argument("--accel", default="kdtree", help="the accelerator both time (kdtree, bvh8)")
    args = ap.parse_args()
    env_a, env_b = parse_env(args.env_a), parse_env(args.env_b)
    ratios = []
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "bench.json")
        print(f"{'scene':<11} {'set':<8} {'mode':<9} {'A Mrays/s':>10} {'B Mrays/s':>10} "
              f"{'B/A':>6}  checksums")
        for scene in args.scenes.split(","):
            rounds = []
            for _ in range(args.rounds):
                a = bench(args.a, env_a, scene, args, out)
                b = bench(args.b, env_b, scene, args, out)
                rounds.append((a, b))
            label = scene.partition("=")[0]
            for key in rounds[0][0]:
                a_rates = [r[0][key][0] for r in rounds]
                b_rates = [r[1][key][0] for r in rounds]
                ratio = statistics.median(rb / ra for ra, rb in zip(a_rates, b_rates))
                same = all(r[0][key][1] == r[1][key][1] for r in rounds)
                ratios.append(ratio)
                print(f"{label:<11} {key[0]:<8} {key[1]:<9} {statistics.median(a_rates):>10.3f} "
                      f"{statistics.median(b_rates):>10.3f} {ratio:>6.3f}  "
                      f"{'same' if same else 'DIFFER'}", flush=True)
    geo = statistics.geometric_mean(ratios)
    print(f"B/A over {len(ratios)} rows: geometric mean {geo:.3f}, "
          f"min {min(ratios):.3f}, max {max(ratios):.3f}")


if __name__ == "__main__":
    sys.exit(main())
