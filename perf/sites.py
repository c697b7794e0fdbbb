#!/usr/bin/env python3
"""Cost per call site inside one function, inlined code included.

The stream kernel is one function after inlining (`walk_lanes`: the SIMD step, the
leaf tests, the pops, the ray starts), so `perf report` puts nearly all of its time
on one symbol. This script maps every sampled instruction back to the source line of
the function that the inlined code was called from (`addr2line -i` walks the inline
chain), and sums the cost per such line: the split by part of an iteration.

It reads either profile:

    # samples on the real CPU (cpu-clock is enough; no hardware counters needed)
    perf record -o perf.data BIN bench conference --rays RAYS/conference \\
        --sets diffuse --modes stream --threads 1 --repeat 20
    python3 perf/sites.py perf.data BIN

    # instructions and mispredicted branches, simulated (valgrind has no AVX-512:
    # build BIN with RUSTFLAGS="-C target-cpu=x86-64-v3" for this one)
    valgrind --tool=callgrind --dump-instr=yes --branch-sim=yes \\
        --callgrind-out-file=cg.out BIN bench ... --repeat 1
    python3 perf/sites.py cg.out BIN --rays 786432

BIN must carry line tables: `CARGO_PROFILE_RELEASE_DEBUG=line-tables-only cargo build
--release --target-dir target/lines` gives target/lines/release/raypack, the same
code as the release build. `--function` names the function to split (default
`walk_lanes`), `--depth` how many inline levels below it name a site (default 1),
`--rays` divides the callgrind counts by a ray count (per-ray figures).
"""

import argparse
import collections
import re
import subprocess
import sys


def run(cmd, **kw):
    """`cmd`'s standard output; exits with a one-line error when it fails."""
    try:
        return subprocess.run(cmd, capture_output=True, text=True, check=True, **kw).stdout
    except FileNotFoundError:
        sys.exit(f"sites.py: {cmd[0]} not found (it is needed for this profile)")
    except subprocess.CalledProcessError as e:
        sys.exit(f"sites.py: {' '.join(cmd[:3])} ... failed: {e.stderr.strip()[:200]}")


# A perf mmap event of an executable mapping: start, size, file offset, path.
MMAP = re.compile(
    r"PERF_RECORD_MMAP2? .*\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+) .*r-xp (\S+)"
)


def perf_samples(data, binary):
    """Sample counts per file address of `binary` from a perf.data file."""
    out = run(["perf", "script", "-i", data, "--show-mmap-events", "-F", "ip,dso"])
    name = binary.split("/")[-1]
    maps = []
    for line in out.splitlines():
        m = MMAP.search(line)
        if m and m.group(4).split("/")[-1] == name:
            maps.append(tuple(int(g, 16) for g in m.groups()[:3]))
    if not maps:
        sys.exit(f"sites.py: no executable mapping of {name} in {data}")
    delta = file_offset_to_vaddr(binary)
    counts = collections.Counter()
    for line in out.splitlines():
        t = line.split()
        if not t or "PERF_RECORD" in line:
            continue
        try:
            ip = int(t[0], 16)
        except ValueError:
            continue
        for start, size, off in maps:
            if start <= ip < start + size:
                counts[ip - start + off + delta] += 1
                break
    return counts, ["samples"]


def file_offset_to_vaddr(binary):
    """vaddr - file offset of the executable segment (readelf -l)."""
    out = run(["readelf", "-lW", binary])
    for line in out.splitlines():
        t = line.split()
        if t and t[0] == "LOAD" and "E" in t[6:-1]:
            return int(t[2], 16) - int(t[1], 16)
    sys.exit(f"sites.py: no executable LOAD segment in {binary}")


def callgrind_costs(path, function):
    """Event counts per instruction address of the functions named like `function`."""
    names, costs = {}, collections.defaultdict(lambda: None)
    events, cur, last, skip = [], None, 0, False
    with open(path) as f:
        for line in f:
            line = line.rstrip("\n")
            if line.startswith("events:"):
                events = line.split()[1:]
                continue
            m = re.match(r"c?fn=\((\d+)\)(?: (.*))?", line)
            if m:
                if m.group(2):
                    names[m.group(1)] = m.group(2)
                if line.startswith("fn="):
                    cur = m.group(1)
                continue
            if line.startswith("calls="):
                skip = True
                continue
            if not line or line[0] not in "+-*0":
                continue
            t = line.split()
            a = t[0]
            if a.startswith("0x"):
                last = int(a, 16)
            elif a[0] in "+-":
                last += int(a)
            if skip:
                skip = False
                continue
            if function in names.get(cur, ""):
                v = [int(x) for x in t[2:]] + [0] * len(events)
                c = costs[last] or [0] * len(events)
                costs[last] = [x + y for x, y in zip(c, v)]
    return {a: c for a, c in costs.items() if c}, events


def inline_chains(binary, addrs):
    """Address -> [(function, file:line)], outermost frame first."""
    out = run(
        ["addr2line", "-a", "-i", "-f", "-C", "-e", binary],
        input="\n".join(hex(a) for a in addrs),
    ).splitlines()
    chains, cur, i = {}, None, 0
    while i < len(out):
        if out[i].startswith("0x"):
            cur = int(out[i], 16)
            chains[cur] = []
            i += 1
        else:
            chains[cur].append((out[i], out[i + 1]))
            i += 2
    return {a: c[::-1] for a, c in chains.items()}


def source(loc):
    """`  | text` of the source line at `loc` (path:line), when the file is readable."""
    path, _, line = loc.rpartition(":")
    try:
        with open(path) as f:
            return "  | " + f.readlines()[int(line) - 1].strip()[:60]
    except (OSError, ValueError, IndexError):
        return ""


def main():
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("profile", help="perf.data or a callgrind.out file")
    ap.add_argument("binary", help="the profiled binary, with line tables")
    ap.add_argument("--function", default="walk_lanes")
    ap.add_argument("--depth", type=int, default=1)
    ap.add_argument("--rays", type=float, default=0, help="divide callgrind counts by this")
    ap.add_argument("--top", type=int, default=25)
    args = ap.parse_args()

    try:
        with open(args.profile, "rb") as f:
            callgrind = f.read(16).startswith(b"# callgrind")
    except OSError as e:
        sys.exit(f"sites.py: {args.profile}: {e.strerror}")
    if callgrind:
        costs, events = callgrind_costs(args.profile, args.function)
    else:
        counts, events = perf_samples(args.profile, args.binary)
        costs = {a: [c] for a, c in counts.items()}
    chains = inline_chains(args.binary, list(costs))
    total = [0] * len(events)
    inside = [0] * len(events)
    sites = collections.defaultdict(lambda: [0] * len(events))
    for a, c in costs.items():
        total = [x + y for x, y in zip(total, c)]
        chain = chains.get(a, [])
        top = next((k for k, (fn, _) in enumerate(chain) if args.function in fn), None)
        if top is None:
            continue
        inside = [x + y for x, y in zip(inside, c)]
        # The outermost frame is the function itself; the site is the line in it (and
        # `depth - 1` more levels) that the sampled code was inlined from.
        below = chain[top:]
        key = tuple(loc for _, loc in below[: args.depth + 1][1:]) or (below[0][1],)
        sites[key] = [x + y for x, y in zip(sites[key], c)]
    if not any(inside):
        sys.exit(f"sites.py: nothing in a function named like {args.function!r}")
    if not callgrind:
        print(f"{args.function}: {100 * inside[0] / total[0]:.1f}% of all {events[0]}")
    head = " ".join(f"{e:>10}" for e in events)
    print(f"{'share':>7} {head}  site")
    per = args.rays if callgrind and args.rays else 1
    for key, c in sorted(sites.items(), key=lambda kv: -kv[1][0])[: args.top]:
        vals = " ".join(f"{x / per:>10.1f}" if per != 1 else f"{x:>10}" for x in c)
        name = " > ".join(loc.split("/")[-1] for loc in key)
        print(f"{100 * c[0] / inside[0]:6.1f}% {vals}  {name}{source(key[0])}")


if __name__ == "__main__":
    main()
