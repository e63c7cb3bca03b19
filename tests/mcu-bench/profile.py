#!/usr/bin/env python3
"""Instructions by function in the bench's timed sections, from QEMU's execution log.

QEMU run with `-d exec,nochain,in_asm` logs each translated block's instructions once
(`IN:`) and a `Trace` line, with the block's function, every time it runs. The bench built
with the feature `profile` calls `section_marker` before and after each timed section;
this script counts, per section, each block's instructions every time it runs, by
function, and prints the mean over the last sections asked for.

    python3 tests/mcu-bench/profile.py LOG [--last N] [--top K]
"""

import argparse
import collections
import re
import shutil
import subprocess
import sys

TRACE = re.compile(r"^Trace \d+: (0x[0-9a-f]+) \[[0-9a-f]+/([0-9a-f]+)/[0-9a-f]+/[0-9a-f]+\] ?(.*)$")
INSN = re.compile(r"^0x([0-9a-f]+):")
MARKER = "section_marker"


def sections(log):
    """Per timed section, a Counter of instructions by (mangled) function."""
    # One guest address can have several translations (under -icount QEMU retranslates a
    # block shorter where it must stop early), so sizes are kept by the translation's host
    # address, the first field of a `Trace` line: a block is listed (`IN:`) when it is
    # translated, and the next `Trace` line is its first run.
    size = {}
    block = None  # instructions of the block being listed after an `IN:` line
    listed = None  # a listed block's size, until its first run names its translation
    found, current = [], None
    with open(log, errors="replace") as f:
        for line in f:
            if line.startswith("IN:"):
                block = 0
                continue
            if block is not None:
                if INSN.match(line):
                    block += 1
                    continue
                if block:
                    listed = block
                block = None
            m = TRACE.match(line)
            if not m:
                continue
            host, pc, function = m.group(1), int(m.group(2), 16), m.group(3).strip()
            if listed is not None:
                size[host] = listed
                listed = None
            if MARKER in function:
                if current is None:
                    current = collections.Counter()
                else:
                    found.append(current)
                    current = None
            elif current is not None:
                current[function or hex(pc)] += size.get(host, 1)
    return found


def demangled(names):
    """Readable names: demangled where c++filt is there, without Rust's hash suffix."""
    names = list(names)
    if shutil.which("c++filt"):
        out = subprocess.run(["c++filt"], input="\n".join(names), capture_output=True, text=True)
        readable = out.stdout.splitlines()
        if len(readable) == len(names):
            names = readable
    return [re.sub(r"::h[0-9a-f]{16}$", "", n) for n in names]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log")
    parser.add_argument("--last", type=int, default=8, help="sections averaged (the last N)")
    parser.add_argument("--top", type=int, default=20, help="functions listed")
    args = parser.parse_args()
    try:
        found = sections(args.log)
    except OSError as e:
        sys.exit(f"profile: cannot read {args.log}: {e.strerror}")
    if len(found) < args.last or args.last < 1:
        sys.exit(f"profile: {len(found)} timed sections in {args.log}, {args.last} asked for")
    chosen = found[-args.last :]
    total = collections.Counter()
    for s in chosen:
        total.update(s)
    names = list(total)
    merged = collections.Counter()
    for name, readable in zip(names, demangled(names)):
        merged[readable] += total[name]
    n = len(chosen)
    whole = sum(merged.values()) / n
    print(f"instructions per section, mean of the last {n} of {len(found)}: {whole:,.0f}")
    print()
    print("| function | instructions | share |")
    print("|---|---:|---:|")
    for name, count in merged.most_common(args.top):
        print(f"| `{name}` | {count / n:,.0f} | {100 * count / n / whole:.1f} % |")
    rest = sum(c for _, c in merged.most_common()[args.top :]) / n
    if rest:
        print(f"| (the rest) | {rest:,.0f} | {100 * rest / whole:.1f} % |")


if __name__ == "__main__":
    main()
