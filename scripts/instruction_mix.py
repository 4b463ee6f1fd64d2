#!/usr/bin/env python3
# How to run:  scripts/instruction_mix.py CALLGRIND_OUT BINARY DIVISOR [--top N]
#   (called by `scripts/kernel_instructions --mix`; CALLGRIND_OUT must come from
#    `valgrind --tool=callgrind --dump-instr=yes`)
#
# The instructions the element loop executes, by mnemonic, per element: callgrind's count
# of every instruction address of the hottest `element_loops::evaluate_*` function (the
# compiled loop the law ran), joined with `objdump`'s disassembly of that function and
# divided by DIVISOR (elements × passes). An operand on the stack (rsp or rbp) is counted
# apart, as "[stack]": those are register spills and reloads, which is how one tells
# arithmetic from data movement the compiler added. Deterministic, like the count it
# refines. Results: docs/BENCHMARKS.md (session 43).
import collections
import re
import subprocess
import sys


def self_cost_by_address(path):
    """Instruction address → executions, from a callgrind file with per-instruction
    positions (calls= lines give the call's inclusive cost on the next line: skipped)."""
    cost = collections.Counter()
    last = 0
    skip_next = False
    with open(path) as f:
        for line in f:
            if line.startswith("calls="):
                skip_next = True
                continue
            if not line or line[0] not in "0123456789+-*":
                continue
            fields = line.split()
            position = fields[0]
            if position.startswith("0x"):
                address = int(position, 16)
            elif position[0] in "+-":
                step = int(position[1:], 0)
                address = last + step if position[0] == "+" else last - step
            elif position == "*":
                address = last
            else:
                continue
            last = address
            if skip_next:
                skip_next = False
                continue
            if len(fields) >= 3:
                cost[address] += int(fields[2])
    return cost


def hottest_loop(binary, cost):
    """(start, size, name) of the `element_loops::evaluate_` symbol with the most
    executed instructions."""
    symbols = subprocess.run(
        ["nm", "-C", "-S", binary], capture_output=True, text=True, check=True
    ).stdout
    best = None
    for line in symbols.splitlines():
        parts = line.split(None, 3)
        if len(parts) != 4 or "element_loops::evaluate_" not in parts[3]:
            continue
        start, size = int(parts[0], 16), int(parts[1], 16)
        total = sum(c for a, c in cost.items() if start <= a < start + size)
        if best is None or total > best[0]:
            best = (total, start, size, parts[3])
    if best is None or best[0] == 0:
        sys.exit("instruction_mix: no executed element_loops::evaluate_ function")
    return best


def main():
    if len(sys.argv) < 4:
        sys.exit("usage: instruction_mix.py CALLGRIND_OUT BINARY DIVISOR [--top N]")
    path, binary, divisor = sys.argv[1], sys.argv[2], float(sys.argv[3])
    top = int(sys.argv[sys.argv.index("--top") + 1]) if "--top" in sys.argv else 16
    cost = self_cost_by_address(path)
    total, start, size, name = hottest_loop(binary, cost)
    listing = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", "-M", "intel",
         f"--start-address={start}", f"--stop-address={start + size}", binary],
        capture_output=True, text=True, check=True,
    ).stdout
    mix = collections.Counter()
    for line in listing.splitlines():
        m = re.match(r"\s*([0-9a-f]+):\s+(\S+)\s*(.*)", line)
        if not m:
            continue
        executed = cost.get(int(m.group(1), 16), 0)
        if executed:
            on_stack = re.search(r"\[(rsp|rbp)", m.group(3)) is not None
            mix[m.group(2) + (" [stack]" if on_stack else "")] += executed
    spills = sum(v for k, v in mix.items() if k.endswith("[stack]"))
    print(f"  {name}: {total / divisor:.1f} instructions per element "
          f"(self, without callees), {spills / divisor:.1f} with a stack operand")
    shown = mix.most_common(top)
    print("  " + ", ".join(f"{k} {v / divisor:.2f}" for k, v in shown))
    rest = total - sum(v for _, v in shown)
    print(f"  the other {len(mix) - len(shown)} mnemonics: {rest / divisor:.2f}")


if __name__ == "__main__":
    main()
