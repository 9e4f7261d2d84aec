#!/usr/bin/env python3
"""Where a process's resident memory lies, from copies of its /proc/<pid>/smaps: per copy,
the resident MiB of glibc's arena heaps (anonymous regions starting on a 64 MiB boundary,
where threads other than the main one allocate), the main heap ([heap]), other anonymous
mappings of 2 MiB or more (large blocks mapped on their own, or memory mapped without
malloc), the remaining small anonymous mappings, and mapped files.

    pid=$(pgrep -f 'stereosplat bench drive'); sleep 60; cp /proc/$pid/smaps out/smaps_60
    ...
    python3 scripts/smaps_summary.py out/smaps_60 out/smaps_210 out/smaps_410

Prints a Markdown table, one row per copy.
"""
import re
import sys

ARENA_ALIGN = 64 << 20
LARGE_KIB = 2048


def mappings(path):
    """(start address, name, resident KiB) of each mapping in an smaps copy."""
    out, current = [], None
    for line in open(path):
        head = re.match(r"^([0-9a-f]+)-[0-9a-f]+ \S+ \S+ \S+ \S+\s*(.*)$", line)
        if head:
            current = [int(head.group(1), 16), head.group(2).strip() or "[anon]", 0]
            out.append(current)
        elif current is not None and line.startswith("Rss:"):
            current[2] = int(line.split()[1])
    return out


def summary(path):
    """Resident MiB per kind of mapping."""
    kinds = {"arena heaps": 0, "[heap]": 0, "large anonymous": 0, "small anonymous": 0,
             "files": 0, "other": 0}
    for start, name, rss in mappings(path):
        if name == "[anon]":
            if start % ARENA_ALIGN == 0:
                kinds["arena heaps"] += rss
            elif rss >= LARGE_KIB:
                kinds["large anonymous"] += rss
            else:
                kinds["small anonymous"] += rss
        elif name == "[heap]":
            kinds["[heap]"] += rss
        elif name.startswith("/"):
            kinds["files"] += rss
        else:
            kinds["other"] += rss
    return {k: v / 1024 for k, v in kinds.items()}


def main() -> int:
    if len(sys.argv) < 2:
        print(__doc__, file=sys.stderr)
        return 2
    rows = [(p, summary(p)) for p in sys.argv[1:]]
    names = list(rows[0][1])
    print("| copy | total MiB | " + " | ".join(names) + " |")
    print("| --- | ---: | " + " | ".join("---:" for _ in names) + " |")
    for path, kinds in rows:
        cells = " | ".join(f"{kinds[n]:.1f}" for n in names)
        print(f"| {path} | {sum(kinds.values()):.1f} | {cells} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
