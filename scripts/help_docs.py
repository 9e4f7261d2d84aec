#!/usr/bin/env python3
"""Regenerates the "Every flag" section of docs/node.md from the built binary's --help.

Usage: python3 scripts/help_docs.py [path/to/stereosplat]  (default: target/release/stereosplat)

Rewrites what lies between the BEGIN and END GENERATED HELP markers: one `### name` heading
and a text block per subcommand (and per benchmark), in the order the section already has.
"""
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "node.md"
BEGIN, END = "<!-- BEGIN GENERATED HELP -->", "<!-- END GENERATED HELP -->"


def main() -> None:
    binary = sys.argv[1] if len(sys.argv) > 1 else str(ROOT / "target" / "release" / "stereosplat")
    text = DOC.read_text()
    head, rest = text.split(BEGIN, 1)
    section, tail = rest.split(END, 1)
    names = re.findall(r"^### `([^`]+)`$", section, flags=re.M)
    if not names:
        sys.exit("no subcommand headings between the markers")
    blocks = []
    for name in names:
        out = subprocess.run([binary, *name.split(), "--help"], check=True,
                             capture_output=True, text=True).stdout.rstrip()
        blocks.append(f"### `{name}`\n\n```text\n{out}\n```\n")
    DOC.write_text(head + BEGIN + "\n" + "\n".join(blocks) + END + tail)
    print(f"{DOC.relative_to(ROOT)}: {len(names)} subcommands")


if __name__ == "__main__":
    main()
