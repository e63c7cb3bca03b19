#!/usr/bin/env python3
"""Per-region use of a firmware ELF against the regions of its memory.x.

    python3 tests/firmware-size/regions.py MEMORY_X ELF

Reads the ELF's section headers (no binutils needed): every allocated section counts in
the region its address falls in; a section with contents in the file (.data) also counts
in FLASH, where its image is loaded from. Prints one line per region, and the stack (RAM's
end above cortex-m-rt's `_stack_end`, which the stack guard ends). Fails if a region's use
exceeds its size or a section lies outside every region.
"""
import re
import struct
import sys

SHF_ALLOC = 0x2
SHT_NOBITS = 8
SHT_SYMTAB = 2


def regions(memory_x):
    text = re.sub(r"/\*.*?\*/", "", open(memory_x).read(), flags=re.S)
    block = re.search(r"MEMORY\s*\{(.*?)\}", text, flags=re.S).group(1)
    out = []
    for name, origin, length, unit in re.findall(
        r"(\w+)\s*(?:\([^)]*\))?\s*:\s*ORIGIN\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*,"
        r"\s*LENGTH\s*=\s*(0x[0-9a-fA-F]+|\d+)\s*([KM]?)",
        block,
    ):
        scale = {"": 1, "K": 1024, "M": 1024 * 1024}[unit]
        out.append((name, int(origin, 0), int(length, 0) * scale))
    return out


def sections(elf):
    data = open(elf, "rb").read()
    if data[:4] != b"\x7fELF" or data[4] != 1:
        sys.exit(f"{elf}: not a 32-bit ELF")
    shoff, = struct.unpack_from("<I", data, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    heads = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    names = heads[shstrndx][4]

    def name(off, table):
        end = data.index(b"\0", table + off)
        return data[table + off:end].decode()

    secs = [(name(h[0], names), h[1], h[2], h[3], h[5]) for h in heads]
    symbols = {}
    for h in heads:
        if h[1] == SHT_SYMTAB:
            strtab = heads[h[6]][4]
            for k in range(h[5] // 16):
                st_name, st_value = struct.unpack_from("<II", data, h[4] + 16 * k)
                symbols[name(st_name, strtab)] = st_value
    return secs, symbols


def main():
    memory_x, elf = sys.argv[1:3]
    regs = regions(memory_x)
    used = {r[0]: 0 for r in regs}
    secs, symbols = sections(elf)
    bad = []
    for name, kind, flags, addr, size in secs:
        if not flags & SHF_ALLOC or size == 0:
            continue
        home = [r for r in regs if r[1] <= addr and addr + size <= r[1] + r[2]]
        if not home:
            bad.append(f"section {name} at {addr:#x} ({size} bytes) lies in no region")
            continue
        used[home[0][0]] += size
        if kind != SHT_NOBITS and home[0][0] != "FLASH":
            used["FLASH"] += size  # its load image
    print(f"{'region':<8} {'origin':>10} {'size':>9} {'used':>9} {'free':>9}  use")
    for name, origin, length in regs:
        u = used[name]
        print(f"{name:<8} {origin:#010x} {length:>9} {u:>9} {length - u:>9}  {100 * u / length:5.1f} %")
        if u > length:
            bad.append(f"region {name}: {u} bytes used of {length}")
    ram = [r for r in regs if r[0] == "RAM"]
    if ram and "_stack_end" in symbols:
        top = symbols.get("_stack_start", ram[0][1] + ram[0][2])
        print(f"stack: {top - symbols['_stack_end']} bytes, RAM above the statics and the stack guard")
    for b in bad:
        print(f"firmware-size: FAIL: {b}", file=sys.stderr)
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
