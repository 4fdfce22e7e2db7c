#!/usr/bin/env python3
"""The executed count of every instruction of a function, on its disassembly.

`benches/instructions.sh` says how many instructions each part of the step takes per
particle-step; this says which ones. It reads a callgrind profile taken with
`--dump-instr=yes` (self cost per instruction address) and prints the disassembly of the
functions whose names match a pattern, each instruction with its count divided by a unit (the
run's particle-steps, say), so that a loop's body reads as instructions per particle-step: what
a change to the fill, the write-back or the sift must take off, instruction by instruction.
Rounds 28, 33 and 40 of docs/performance-log.md made such profiles by hand; `hot_instructions.sh`
runs the whole chain on a scene.

usage: benches/hot_instructions.py PROFILE BINARY PATTERN [--unit N] [--floor F] [--lines]
       benches/hot_instructions.py --self-test
  PROFILE  callgrind.out file from `valgrind --tool=callgrind --dump-instr=yes`
  BINARY   the profiled binary (its symbols: `nm`, its code: `objdump`)
  PATTERN  a regular expression on the demangled function names (e.g. 'pair_pass::handle_kept')
  --unit   divide the counts by N (default 1)
  --floor  leave out instructions run less than F times the function's most run one (default
           0.05: the cold paths)
  --lines  with the source line of each instruction (a build with line tables)
"""

import argparse
import os
import re
import signal
import subprocess
import sys
from collections import Counter

# A cost line: a position (absolute, `+n`/`-n` relative, `*` the same) per position kind, then
# the event counts.
POSITION = re.compile(r"^(0x[0-9a-fA-F]+|\d+|[+-]\d+|\*)$")


def parse_profile(text: str, binary_name: str) -> Counter:
    """Self cost (the first event, `Ir`) per instruction address of the object whose path ends
    with `binary_name`, from a callgrind profile with instruction positions. Callgrind's format
    compresses positions relative to the line before, names by `(id)`, and follows each
    `calls=` line with the call's inclusive cost, which is not the caller's own and is skipped.
    """
    kinds = ["line"]
    previous = [0]
    objects: dict[str, str] = {}
    in_binary = False
    skip_call_cost = False
    counts: Counter = Counter()
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.startswith("positions:"):
            kinds = line.split(":", 1)[1].split()
            previous = [0] * len(kinds)
            continue
        if line.startswith(("ob=", "cob=")):
            # An object's name is given once, at the first `ob=` or `cob=` (a call's object)
            # that names it, and by its `(id)` after that.
            spec = line.split("=", 1)[1].strip()
            match = re.match(r"^\((\d+)\)\s*(.*)$", spec)
            if match:
                ident, name = match.group(1), match.group(2)
                if name:
                    objects[ident] = name
                name = objects.get(ident, "")
            else:
                name = spec
            if line.startswith("ob="):
                in_binary = name.endswith(binary_name)
            continue
        if line.startswith("calls="):
            skip_call_cost = True
            continue
        fields = line.split()
        if "=" in fields[0] or ":" in fields[0]:
            # fn=, fl=, fi=, fe=, cfn=, jump=, jcnd=, events:, summary: ...
            continue
        if len(fields) < len(kinds) or not all(POSITION.match(f) for f in fields[: len(kinds)]):
            continue
        position = []
        for field, last in zip(fields[: len(kinds)], previous):
            if field == "*":
                position.append(last)
            elif field[0] in "+-":
                position.append(last + int(field))
            else:
                position.append(int(field, 0))
        previous = position
        if skip_call_cost:
            skip_call_cost = False
            continue
        if in_binary and "instr" in kinds and len(fields) > len(kinds):
            counts[position[kinds.index("instr")]] += int(fields[len(kinds)])
    return counts


def functions(binary: str, pattern: str) -> list[tuple[int, int, str]]:
    """(start, size, demangled name) of the binary's functions whose names match `pattern`."""
    listing = subprocess.run(
        ["nm", "-S", "-C", "--defined-only", binary], capture_output=True, text=True, check=True
    ).stdout
    found = []
    for line in listing.splitlines():
        parts = line.split(None, 3)
        if len(parts) == 4 and parts[2] in "tT" and re.search(pattern, parts[3]):
            found.append((int(parts[0], 16), int(parts[1], 16), parts[3]))
    return found


def short_path(path: str) -> str:
    """A source path without the toolchain's, the registry's or this checkout's prefix."""
    path = re.sub(r"^/rustc/[0-9a-f]+/library/", "std: ", path)
    path = re.sub(r"^.*/registry/src/[^/]+/", "", path)
    root = os.getcwd() + "/"
    return path[len(root):] if path.startswith(root) else path


INSTRUCTION = re.compile(r"^\s*([0-9a-f]+):\t(.*)$")


def annotate(disassembly: str, counts: Counter, unit: float, floor: float, lines: bool) -> list[str]:
    """Lines of `disassembly` (objdump -d, with -l for source lines) with each instruction's count
    over `unit`; instructions run less than `floor` times the most run one are left out."""
    # (source line, address, instruction) of each instruction, read once.
    instructions = []
    source = None
    for raw in disassembly.splitlines():
        match = INSTRUCTION.match(raw)
        if match:
            instructions.append((source, int(match.group(1), 16), match.group(2)))
        elif lines and re.match(r"^/.*:\d+", raw):
            source = short_path(raw.split(" (discriminator")[0])
    top = max((counts.get(address, 0) for _, address, _ in instructions), default=0)
    out = []
    shown_source = None
    for source, address, text in instructions:
        count = counts.get(address, 0)
        if top == 0 or count < floor * top or count == 0:
            continue
        if lines and source != shown_source:
            out.append(f"{'':>12}   {source}")
            shown_source = source
        # objdump names a branch target `<function+0x..>` in full (generic arguments and all):
        # the offset is enough.
        text = re.sub(r"\s<(.*)>$", lambda m: " <" + (re.findall(r"\+0x[0-9a-f]+$", m.group(1)) or [""])[0] + ">", text)
        out.append(f"{count / unit:12.3f}   {address:x}  {' '.join(text.split())}")
    return out


def report(profile: str, binary: str, pattern: str, unit: float, floor: float, lines: bool) -> None:
    counts = parse_profile(open(profile, encoding="utf-8", errors="replace").read(), binary.rsplit("/", 1)[-1])
    if not counts:
        sys.exit(f"{profile}: no instruction counts for {binary} (was it taken with --dump-instr=yes?)")
    chosen = []
    for start, size, name in functions(binary, pattern):
        inside = [c for a, c in counts.items() if start <= a < start + size]
        if sum(inside):
            chosen.append((sum(inside), max(inside), start, size, name))
    if not chosen:
        sys.exit(f"no executed function of {binary} matches {pattern!r}")
    everything = sum(counts.values())
    for total, top, start, size, name in sorted(chosen, reverse=True):
        print(f"== {name}")
        print(f"   {total / unit:.1f} instructions per unit ({100 * total / everything:.1f} % of the binary's);"
              f" its most run instruction {top / unit:.3f} times per unit, {total / top:.1f} instructions per such run")
        command = ["objdump", "-d", "--no-show-raw-insn", "-C", f"--start-address={start:#x}",
                   f"--stop-address={start + size:#x}", binary]
        if lines:
            command.insert(2, "-l")
        disassembly = subprocess.run(command, capture_output=True, text=True, check=True).stdout
        for line in annotate(disassembly, counts, unit, floor, lines):
            print(line)
        print()


SAMPLE = """# callgrind format
version: 1
positions: instr line
events: Ir
summary: 999

ob=(1) /usr/lib/x86_64-linux-gnu/libm.so.6
fl=(1) e_pow.c
fn=(1) pow
0x1000 10 7
+4 * 7

cob=(2) /tmp/build/release/am-sim
cfn=(9) main
calls=1 0x1000 1
* * 4

ob=(2)
fl=(2) /work/src/forces/pair_pass.rs
fn=(2) am_sim::forces::pair_pass::handle_kept
0x1000 650 100
+3 +1 100
* * 5
+2 -1 40
cfn=(1)
calls=40 0x2000 12
* * 3000
+5 * 40
fn=(3) am_sim::other
ob=(1)
0x1010 11 9
ob=(2)
0x100c 1 2
"""

SAMPLE_DISASSEMBLY = """
0000000000001000 <am_sim::forces::pair_pass::handle_kept>:
/work/src/forces/pair_pass.rs:650
    1000:\tmov    (%rbx),%edx
/work/src/forces/pair_pass.rs:651
    1003:\tlea    (%rdx,%rdx,2),%rdi
    1005:\tcall   2000 <pow@plt>
    100a:\tjne    1000 <am_sim::forces::pair_pass::handle_kept+0x0>
    100c:\tud2
"""


def self_test() -> None:
    counts = parse_profile(SAMPLE, "am-sim")
    # The binary's addresses only (libm's 0x1000 and 0x1010 are another object's; the binary
    # named first by a call's `cob=`, and the call's cost from libm skipped), the
    # repeated position summed, the call's inclusive 3000 (at the call's own position) skipped,
    # and the relative positions followed through it (0x1005 + 5 = 0x100a).
    expected = Counter({0x1000: 100, 0x1003: 105, 0x1005: 40, 0x100A: 40, 0x100C: 2})
    assert counts == expected, f"parsed {dict(counts)}, expected {dict(expected)}"
    shown = annotate(SAMPLE_DISASSEMBLY, counts, unit=10.0, floor=0.05, lines=True)
    # 0x100c (2 of the top 105) is below the floor; the source lines appear where they change;
    # branch targets keep their offset only.
    assert shown == [
        "               /work/src/forces/pair_pass.rs:650",
        "      10.000   1000  mov (%rbx),%edx",
        "               /work/src/forces/pair_pass.rs:651",
        "      10.500   1003  lea (%rdx,%rdx,2),%rdi",
        "       4.000   1005  call 2000 <>",
        "       4.000   100a  jne 1000 <+0x0>",
    ], "\n".join(shown)
    print("hot_instructions self-test: the profile's positions, objects and calls read as they must")


def main() -> None:
    # Read through `head`: stop quietly when the reader has had enough.
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    if sys.argv[1:] == ["--self-test"]:
        self_test()
        return
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("profile")
    parser.add_argument("binary")
    parser.add_argument("pattern")
    parser.add_argument("--unit", type=float, default=1.0)
    parser.add_argument("--floor", type=float, default=0.05)
    parser.add_argument("--lines", action="store_true")
    args = parser.parse_args()
    report(args.profile, args.binary, args.pattern, args.unit, args.floor, args.lines)


if __name__ == "__main__":
    main()
