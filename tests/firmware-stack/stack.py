#!/usr/bin/env python3
"""Static stack analysis of the firmware's release ELF (Cortex-M, Thumb-2).

Reads `arm-none-eabi-objdump -d` (or `llvm-objdump -d`) output and the symbol table, and
computes for every function its own frame (the bytes its prologue takes: `push`, `vpush`,
`sub sp, #N`) and, along direct calls (`bl`, `b.w` to a function start), the deepest path.

The stack's worst case is taken as:
  thread mode: the deepest path from `main` (the executor's loop) plus the deepest path
               from any task's poll function (`TaskStorage<F>::poll`: the executor calls
               them through a pointer, which no direct call shows);
  interrupts:  the deepest interrupt handler (distinct vector-table symbols) plus, since an
               interrupt-priority executor polls its tasks from its handler through the same
               pointers, the deepest task poll again, plus the 104-byte exception frame with
               floating-point state. Handlers of one priority do not nest; the firmware has
               one executor above thread mode.
Indirect calls (`blx rN`) other than the executor's are not followed; their sites are
counted and printed. Recursion is reported and its cycle counted once.

  python3 stack.py DISASSEMBLY.txt SYMBOLS.txt STACK_BYTES [--max-frame BYTES] [--margin F]

Prints the largest frames, the worst path, and a verdict; exits 1 when the largest single
frame exceeds --max-frame (16 KiB) or the worst case leaves less than --margin (25 %) of
the stack.
"""
import re
import sys

EXCEPTION_FRAME = 104  # r0-r3, r12, lr, pc, xPSR, s0-s15, FPSCR, alignment


def parse(dis_path):
    frames, calls, indirect, dynamic = {}, {}, {}, set()
    cur = None
    fn_re = re.compile(r"^[0-9a-f]+ <(.+)>:$")
    push_re = re.compile(r"\t(?:push|stmdb)(?:\.w)?\s+(?:sp!, )?\{([^}]*)\}")
    vpush_re = re.compile(r"\tvpush\s+\{([^}]*)\}")
    sub_re = re.compile(r"\tsub(?:w|\.w)?\s+sp, (?:sp, )?#(\d+)")
    subreg_re = re.compile(r"\tsub(?:\.w)?\s+sp, (?:sp, )?r\d+")
    call_re = re.compile(r"\t(bl|b\.w)\s+(?:0x)?[0-9a-f]+ <([^>+]+)>")
    blx_re = re.compile(r"\tblx\s+r\d+")
    for line in open(dis_path, encoding="utf-8", errors="replace"):
        line = line.rstrip("\n")
        m = fn_re.match(line)
        # llvm-objdump also labels ARM mapping symbols (`$t`, `$d`: code and data inside a
        # function, e.g. after a jump table): they are not functions.
        if m and not m.group(1).startswith("$"):
            cur = m.group(1)
            frames.setdefault(cur, 0)
            calls.setdefault(cur, set())
            continue
        if cur is None or m:
            continue
        m = push_re.search(line)
        if m:
            frames[cur] += 4 * count_regs(m.group(1))
            continue
        m = vpush_re.search(line)
        if m:
            regs = count_regs(m.group(1))
            size = 8 if "d" in m.group(1) else 4
            frames[cur] += size * regs
            continue
        m = sub_re.search(line)
        if m:
            frames[cur] += int(m.group(1))
            continue
        if subreg_re.search(line):
            dynamic.add(cur)
            continue
        m = call_re.search(line)
        if m and m.group(2) != cur:
            calls[cur].add(m.group(2))
            continue
        if blx_re.search(line):
            indirect[cur] = indirect.get(cur, 0) + 1
    return frames, calls, indirect, dynamic


def count_regs(spec):
    n = 0
    for part in spec.split(","):
        part = part.strip()
        m = re.match(r"([rds])(\d+)-[rds](\d+)", part)
        if m:
            n += int(m.group(3)) - int(m.group(2)) + 1
        elif part:
            n += 1
    return n


def deepest(root, frames, calls, memo, stack, cycles):
    if root in memo:
        return memo[root]
    if root in stack:
        cycles.add(root)
        return (0, [])
    stack.add(root)
    best = (0, [])
    for callee in calls.get(root, ()):
        if callee not in frames:
            continue
        d = deepest(callee, frames, calls, memo, stack, cycles)
        if d[0] > best[0]:
            best = d
    stack.discard(root)
    result = (frames.get(root, 0) + best[0], [root] + best[1])
    memo[root] = result
    return result


def handlers(sym_path):
    """Interrupt and exception handlers: vector-table names (upper case) with their own
    code, not the default handler's."""
    default, named = None, []
    for line in open(sym_path):
        parts = line.split()
        if len(parts) != 3 or parts[1] not in ("T", "t"):
            continue
        addr, name = parts[0], parts[2]
        if name == "DefaultHandler":
            default = addr
        elif re.fullmatch(r"[A-Z][A-Z0-9_]+", name):
            named.append((addr, name))
    return [n for a, n in named if a != default]


def short(name, width=110):
    return name if len(name) <= width else name[: width - 1] + "…"


def main():
    args = sys.argv[1:]
    max_frame, margin = 16 * 1024, 0.25
    if "--max-frame" in args:
        i = args.index("--max-frame")
        max_frame = int(args[i + 1])
        del args[i : i + 2]
    if "--margin" in args:
        i = args.index("--margin")
        margin = float(args[i + 1])
        del args[i : i + 2]
    dis_path, sym_path, stack_bytes = args[0], args[1], int(args[2])
    frames, calls, indirect, dynamic = parse(dis_path)
    memo, cycles = {}, set()
    thread, path = deepest("main", frames, calls, memo, set(), cycles)
    tasks = [f for f in frames if "TaskStorage" in f and f.endswith(tuple("0123456789E")) and "4poll" in f]
    task_best = (0, [])
    for t in tasks:
        d = deepest(t, frames, calls, memo, set(), cycles)
        if d[0] > task_best[0]:
            task_best = d
    isr_best = (0, [])
    for h in handlers(sym_path):
        if h in frames:
            d = deepest(h, frames, calls, memo, set(), cycles)
            if d[0] > isr_best[0]:
                isr_best = d
    worst = thread + task_best[0] + isr_best[0] + task_best[0] + EXCEPTION_FRAME
    largest = sorted(frames.items(), key=lambda kv: -kv[1])[:5]
    print("largest frames:")
    for name, size in largest:
        print(f"  {size:>7} B  {short(name)}")
    print(f"thread mode: main {thread} B + deepest task poll {task_best[0]} B "
          f"({len(tasks)} tasks)")
    for name in task_best[1][:12]:
        print(f"  {frames[name]:>7} B  {short(name)}")
    print(f"interrupts: deepest handler {isr_best[0]} B "
          f"({short(isr_best[1][0]) if isr_best[1] else 'none'}) + a task poll "
          f"{task_best[0]} B + {EXCEPTION_FRAME} B exception frame")
    sites = sum(indirect.values())
    print(f"not followed: {sites} indirect call sites in {len(indirect)} functions; "
          f"{len(dynamic)} functions with a variable-size frame; {len(cycles)} recursive")
    print(f"static worst path: {worst} bytes of {stack_bytes}")
    ok = True
    if largest and largest[0][1] > max_frame:
        print(f"FAIL: a single frame of {largest[0][1]} B is over {max_frame} B")
        ok = False
    if worst > (1 - margin) * stack_bytes:
        print(f"FAIL: the worst path leaves less than {margin:.0%} of the stack")
        ok = False
    if ok:
        print(f"ok: {100 * (1 - worst / stack_bytes):.0f} % of the stack to spare, "
              f"largest frame {largest[0][1] if largest else 0} B")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
