#!/usr/bin/env python3
"""Checks that the vector builds of the step's kernels call no function of their own.

`simd::dispatch` compiles each kernel (the pair and wall contact laws, the kicks and drift, the
temperatures' update) into `loop_avx2` and `loop_avx512`, functions built for those instruction
sets. A function the kernel reaches and the compiler leaves out of line is compiled for the
binary's own target (SSE2) and called once per lane: the lanes are no longer a vector. In a
throw-away build of the thirty-eighth round (docs/performance-log.md) three laws went out of line
that way and the 19.2k LIGGGHTS bed's step ran at 0.30 times its speed; in the tree as it was,
`contact::normal_force` was called per lane from every kernel with bond laws. No timing shows
such a cliff exactly on a noisy host, the disassembly does: this check reads every call and jump
in the vector builds and fails on any that leaves the kernel for code of am-sim or another
crate. What may stay out of line is the C library's (`pow`, `memset`: symbols with `@`) and the
cold panics of a failed check (`core::panicking`, a slice index out of bounds).

usage: scripts/check_kernels.py [BINARY]   (default: target/release/am-sim; needs objdump)
       scripts/check_kernels.py --self-test   (the reading of objdump's lines, on a sample)
"""

import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

# Calls a vector build may make: the C library's, and the panics of a failed check (cold paths).
ALLOWED = (
    re.compile(r"@"),
    re.compile(r"^core::panicking::"),
    re.compile(r"^core::slice::index::"),
    re.compile(r"^core::option::expect_failed"),
    re.compile(r"^core::result::unwrap_failed"),
)
FUNCTION = re.compile(r"^[0-9a-f]+ <(.+)>:$")
KERNEL = re.compile(r"^am_sim::simd::loop_avx(2|512)\b")
# A call or a jump: its mnemonic and operand, and the symbol objdump names at the end of the line
# (`<symbol>`, `<symbol+0x12>`, or after `#` for a call through the GOT); a jump table has none.
BRANCH = re.compile(r"^\s*[0-9a-f]+:\t(call|jmp|j[a-z]{1,3})\s+(\S+)")
TARGET = re.compile(r"\s<(.*)>\s*$")


def scan(disassembly: str) -> tuple[int, dict[str, set[str]]]:
    """The number of vector builds in `disassembly` (objdump -d -C) and, per build, what it
    calls or jumps to outside itself that is not allowed."""
    kernels = 0
    offending = defaultdict(set)
    current = None
    for line in disassembly.splitlines():
        header = FUNCTION.match(line)
        if header:
            current = header.group(1) if KERNEL.match(header.group(1)) else None
            kernels += current is not None
            continue
        if current is None:
            continue
        branch = BRANCH.match(line)
        if not branch:
            continue
        mnemonic, operand = branch.group(1), branch.group(2)
        named = TARGET.search(line)
        if named is None:
            # A jump through a register or a table stays in the function (a `match`); a call
            # through one leaves it for code unknown here.
            if mnemonic == "call":
                offending[current].add(f"an indirect call ({operand})")
            continue
        target = re.sub(r"\+0x[0-9a-f]+$", "", named.group(1))
        # A branch within the kernel (its own symbol, with or without an offset).
        if target == current:
            continue
        if any(rule.search(target) for rule in ALLOWED):
            continue
        offending[current].add(target)
    return kernels, dict(offending)


# objdump's lines as they come for each case the check must tell apart (release names, which
# carry no generic arguments), and what `scan` must find in them.
SAMPLE = """\
0000000000243e70 <am_sim::contact::normal_force>:
  243e70:\tpush   %rbp
  243e71:\tcall   243f00 <am_sim::contact::hertz_parts>
0000000000258ce0 <am_sim::simd::loop_avx512>:
  258ce0:\tvmovupd (%rdi),%zmm0
  258ce6:\tjne    258d10 <am_sim::simd::loop_avx512+0x30>
  258cf0:\tcall   243e70 <am_sim::contact::normal_force>
  258cf5:\tcall   *0x5ff77f(%rip)        # 80eb80 <pow@GLIBC_2.29>
  258cfb:\tjmp    *%rdx
  258d00:\tcall   2a0000 <core::panicking::panic_bounds_check>
  258d05:\tjmp    2a0100 <<glam::f64::dvec3::DVec3 as core::ops::arith::Add>::add>
0000000000259000 <am_sim::simd::loop_avx2>:
  259000:\tcall   *%rax
  259002:\tjb     259000 <am_sim::simd::loop_avx2>
  259004:\tret
0000000000259100 <am_sim::simd::dispatch>:
  259100:\tcall   258ce0 <am_sim::simd::loop_avx512>
"""


def self_test() -> int:
    kernels, offending = scan(SAMPLE)
    expected = {
        "am_sim::simd::loop_avx512": {
            "am_sim::contact::normal_force",
            "<glam::f64::dvec3::DVec3 as core::ops::arith::Add>::add",
        },
        "am_sim::simd::loop_avx2": {"an indirect call (*%rax)"},
    }
    if (kernels, offending) != (2, expected):
        print(f"check_kernels --self-test: found {kernels} builds, {offending}", file=sys.stderr)
        print(f"check_kernels --self-test: expected 2 builds, {expected}", file=sys.stderr)
        return 1
    print("check_kernels --self-test: passed")
    return 0


def main() -> int:
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    binary = Path(sys.argv[1] if len(sys.argv) > 1 else "target/release/am-sim")
    if not binary.is_file():
        print(f"check_kernels: {binary}: no such binary (cargo build --release first)", file=sys.stderr)
        return 1
    disassembly = subprocess.run(
        ["objdump", "-d", "-C", "--no-show-raw-insn", str(binary)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    kernels, offending = scan(disassembly)
    if kernels == 0:
        print(f"check_kernels: no vector build (am_sim::simd::loop_avx*) found in {binary}", file=sys.stderr)
        return 1
    if offending:
        for kernel, targets in sorted(offending.items()):
            for target in sorted(targets):
                print(f"check_kernels: {kernel} calls {target} out of line", file=sys.stderr)
        print(
            "check_kernels: mark what the kernel reaches #[inline(always)] (src/simd.rs, Kernel)",
            file=sys.stderr,
        )
        return 1
    print(f"check_kernels: {kernels} vector builds, none calls a function of its own ({binary})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
