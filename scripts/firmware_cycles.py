"""Cycles of one firmware tick on a Cortex-M4F at 168 MHz (``make firmware-cycles``).

Instructions per tick are counted by QEMU (``-icount shift=0`` on its netduinoplus2, an
STM32F405 Cortex-M4F: firmware/board/m4f_cycles.c brackets each tick with the SysTick on the
168 MHz processor clock of that virtual time, calibrated on a loop of known length). QEMU counts
instructions, not cycles; the cycles per instruction are bounded from the generated code: every
instruction of the functions a tick can reach (the call graph from ``board_tick`` in the ELF's
disassembly) priced at its Cortex-M4 worst case (Technical Reference Manual, tables 3-1 and
7-1: a branch with its 3-cycle pipeline refill, every load unpipelined, LDM/STM/PUSH/POP and
VPUSH/VPOP per register, VDIV/VSQRT 14, UDIV/SDIV 12, fused multiply-adds 3), weighted by how
often each appears in that code. Flash wait states are taken as hidden by the STM32F4's ART
accelerator (code run from SRAM or CCM would need none).

Usage: python scripts/firmware_cycles.py ELF QEMU_OUTPUT
"""

from __future__ import annotations

import re
import subprocess
import sys

BUDGET_CYCLES = 168_000_000 // 10_000  # one 10 kHz tick at 168 MHz
BRANCH = 4  # taken, with a full pipeline refill
CONDS = {"eq", "ne", "cs", "cc", "mi", "pl", "vs", "vc", "hi", "ls", "ge", "lt", "gt", "le", "hs"}
CONDS |= {"lo"}


def _cost(mnemonic: str, operands: str) -> int:
    m = mnemonic.split(".")[0]
    regs = (
        len(re.findall(r"\b[rsd]\d+\b|\blr\b|\bpc\b", operands.split("{")[-1]))
        if "{" in operands
        else 1
    )
    if m in {"b", "bl", "bx", "blx", "cbz", "cbnz"} or (
        m.startswith("b")
        and len(m) == 3
        and m[1:]
        in {
            "eq",
            "ne",
            "cs",
            "cc",
            "mi",
            "pl",
            "vs",
            "vc",
            "hi",
            "ls",
            "ge",
            "lt",
            "gt",
            "le",
            "hs",
            "lo",
        }
    ):
        return BRANCH
    if m in {
        "push",
        "pop",
        "ldmia",
        "ldmdb",
        "stmia",
        "stmdb",
        "ldm",
        "stm",
        "vpush",
        "vpop",
        "vldmia",
        "vldmdb",
        "vstmia",
        "vstmdb",
    }:
        return 1 + regs + (3 if "pc" in operands else 0)
    if m in {"ldrd", "strd"}:
        return 3
    if m.startswith(("ldr", "str")):
        return 2
    if m in {"vldr", "vstr"}:
        return 3 if ".64" in mnemonic or re.search(r"\bd\d+", operands) else 2
    if m in {"vdiv", "vsqrt"}:
        return 14
    if m in {"udiv", "sdiv"}:
        return 12
    if m in {"vmla", "vmls", "vfma", "vfms", "vnmla", "vnmls", "vfnma", "vfnms"}:
        return 3
    if m in {"mul", "mla", "mls"}:
        return 2
    if m == "vmov" and operands.count(",") >= 2:
        return 2
    return 1


def tick_code(elf: str, root: str = "board_tick") -> dict[str, list[tuple[str, str]]]:
    """Instructions of every function reachable from ``root`` (calls and tail calls)."""
    text = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", elf],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    funcs: dict[str, list[tuple[str, str]]] = {}
    calls: dict[str, set[str]] = {}
    current = None
    for line in text.splitlines():
        head = re.match(r"^[0-9a-f]+ <([^>]+)>:$", line)
        if head:
            current = head.group(1)
            funcs[current], calls[current] = [], set()
            continue
        ins = re.match(r"^\s+[0-9a-f]+:\s+(\S+)\s*(.*)$", line)
        if ins and current is not None:
            mnemonic, operands = ins.group(1), ins.group(2)
            funcs[current].append((mnemonic, operands))
            target = re.search(r"<([^>+]+)>", operands)
            if (
                target
                and mnemonic.split(".")[0] in {"bl", "b", "blx"}
                and target.group(1) != current
            ):
                calls[current].add(target.group(1))
    seen, todo = set(), [root]
    while todo:
        f = todo.pop()
        if f in seen or f not in funcs:
            continue
        seen.add(f)
        todo += calls[f]
    return {f: funcs[f] for f in seen}


def main(elf: str, qemu_output: str) -> None:
    counts = dict(re.findall(r"^(.*?): (\d+)$", qemu_output, flags=re.M))
    per_insn = int(counts["calibration systick counts per 4000 instructions"]) / 4000.0
    code = tick_code(elf)
    insns = [i for body in code.values() for i in body]
    cpi = sum(_cost(m, o) for m, o in insns) / len(insns)
    rows = [
        ("worst tick (a 16-row chunk handled)", int(counts["worst tick systick counts"])),
        (
            "worst armed tick (a longest frame refused, telemetry)",
            int(counts["worst armed tick systick counts"]),
        ),
        ("mean armed tick", int(counts["mean armed tick systick counts x100"]) / 100.0),
    ]
    print(
        f"tick code: {len(code)} functions, {len(insns)} instructions; worst-case CPI of its "
        f"mix {cpi:.2f} (Cortex-M4 TRM, branches with refill, loads unpipelined)"
    )
    print(
        "| tick | instructions (QEMU) | cycles at CPI 1 | cycles at the worst-case CPI "
        "| of the 100 us budget |"
    )
    print("|---|---|---|---|---|")
    for label, systick in rows:
        n = systick / per_insn
        share = 100 * n * cpi / BUDGET_CYCLES
        print(f"| {label} | {n:.0f} | {n:.0f} | {n * cpi:.0f} | {share:.1f} % |")
    bg = int(counts["worst background decode systick counts"]) / per_insn
    print(
        f"background decode (main loop, not in the tick): at most {bg:.0f} instructions per "
        f"64-byte read"
    )


if __name__ == "__main__":
    with open(sys.argv[2], encoding="utf-8") as fh:
        main(sys.argv[1], fh.read())
