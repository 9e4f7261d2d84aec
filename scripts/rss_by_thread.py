#!/usr/bin/env python3
"""Which threads are busy when a process's resident memory jumps.

  python3 scripts/rss_by_thread.py sample TRACE [--match 'bench drive'] [--seconds 900]
      samples the first process whose command line starts with `stereosplat <match>` every
      50 ms: its resident size and the CPU ticks of each of its threads, one line per sample
      (run it beside the command, e.g. `stereosplat bench drive`).
  python3 scripts/rss_by_thread.py spikes TRACE [--over-mib 15]
      lists the samples more than `over-mib` above the median of the 2 s before them (one
      per second at most), how long each lasts, and the threads that used the most CPU in
      the 0.3 s before it; then how often each thread was the busiest.

The bench's own trace (`rss.csv`) samples once a second; this one is fine enough to see a
transient of one bin's work.
"""
import argparse
import collections
import glob
import os
import statistics
import time


def find(match):
    want = [b"stereosplat"] + [w.encode() for w in match.split()]
    for path in glob.glob("/proc/[0-9]*/cmdline"):
        try:
            words = open(path, "rb").read().split(b"\0")
        except OSError:
            continue
        if words[0].endswith(want[0]) and words[1 : len(want)] == want[1:]:
            return int(path.split("/")[2])
    return None


def sample(trace, match, seconds):
    out = open(trace, "w")
    start, pid = time.time(), None
    while time.time() - start < seconds:
        if pid is None or not os.path.exists(f"/proc/{pid}"):
            pid = find(match)
            if pid is None:
                time.sleep(0.2)
                continue
        try:
            rss = next(l for l in open(f"/proc/{pid}/status") if l.startswith("VmRSS")).split()[1]
            threads = []
            for task in glob.glob(f"/proc/{pid}/task/*"):
                try:
                    stat = open(task + "/stat").read()
                except OSError:
                    continue
                name = stat[stat.index("(") + 1 : stat.rindex(")")].replace(" ", "_")
                fields = stat[stat.rindex(")") + 2 :].split()
                threads.append(f"{name}:{int(fields[11]) + int(fields[12])}")
            out.write(f"{time.time() - start:.2f} {rss} {' '.join(threads)}\n")
        except (OSError, StopIteration):
            pid = None
        time.sleep(0.05)


def spikes(trace, over_mib):
    rows = []
    for line in open(trace):
        parts = line.split()
        if len(parts) < 3:
            continue
        ticks = collections.Counter()
        for t in parts[2:]:
            name, value = t.rsplit(":", 1)
            ticks[name] += int(value)
        rows.append((float(parts[0]), int(parts[1]) / 1024, ticks))
    rss = [r[1] for r in rows]
    found, busiest = [], collections.Counter()
    for i in range(40, len(rows)):
        base = statistics.median(rss[i - 40 : i])
        if rss[i] - base <= over_mib or (found and rows[i][0] - found[-1] < 1.0):
            continue
        found.append(rows[i][0])
        before = rows[max(0, i - 6)][2]
        used = sorted(((v - before.get(k, 0), k) for k, v in rows[i][2].items()), reverse=True)
        end = i
        while end + 1 < len(rows) and rows[end][1] - base > over_mib / 2:
            end += 1
        busiest[used[0][1]] += 1
        top = ", ".join(f"{k} {v}" for v, k in used[:3] if v > 0)
        print(f"{rows[i][0]:7.2f} s  {rss[i]:6.1f} MiB  +{rss[i] - base:4.1f}  lasts {rows[end][0] - rows[i][0]:4.2f} s  busy (ticks): {top}")
    print(f"\n{len(found)} jumps of more than {over_mib} MiB in {len(rows)} samples over {rows[-1][0]:.0f} s")
    for name, n in busiest.most_common():
        print(f"busiest thread {name}: {n}")


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)
    s = sub.add_parser("sample")
    s.add_argument("trace")
    s.add_argument("--match", default="bench drive")
    s.add_argument("--seconds", type=float, default=900)
    k = sub.add_parser("spikes")
    k.add_argument("trace")
    k.add_argument("--over-mib", type=float, default=15)
    a = p.parse_args()
    if a.cmd == "sample":
        sample(a.trace, a.match, a.seconds)
    else:
        spikes(a.trace, a.over_mib)


if __name__ == "__main__":
    main()
