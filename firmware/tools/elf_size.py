#!/usr/bin/env python3
"""Flash and static-RAM use of a Cortex-M ELF (no binutils needed).

flash = every allocated section with file contents (PROGBITS) in the flash region
        (.vector_table, .text, .rodata, ... plus the load image of .data);
ram   = .data + .bss (+ .uninit), i.e. static RAM before the stack.
Usage: elf_size.py ELF [--flash-max BYTES] [--ram-max BYTES]; exits 1 when over a limit.
"""
import struct
import sys


def sections(path):
    with open(path, "rb") as f:
        b = f.read()
    if b[:4] != b"\x7fELF" or b[4] != 1 or b[5] != 1:
        raise SystemExit(f"{path}: not a 32-bit little-endian ELF")
    shoff, = struct.unpack_from("<I", b, 0x20)
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", b, 0x2E)
    hdrs = [struct.unpack_from("<IIIIIIIIII", b, shoff + i * shentsize) for i in range(shnum)]
    strtab = hdrs[shstrndx]
    def name(off):
        s = strtab[4] + off
        return b[s:b.index(b"\0", s)].decode()
    for h in hdrs:
        yield name(h[0]), h[1], h[2], h[3], h[5]  # name, type, flags, addr, size


def main():
    args = sys.argv[1:]
    if not args:
        raise SystemExit(__doc__)
    path = args[0]
    lim = {"--flash-max": None, "--ram-max": None}
    for k in lim:
        if k in args:
            lim[k] = int(args[args.index(k) + 1])
    SHF_ALLOC, PROGBITS, NOBITS = 0x2, 1, 8
    flash = data = bss = 0
    for name, typ, flags, addr, size in sections(path):
        if not flags & SHF_ALLOC or size == 0:
            continue
        in_ram = 0x2000_0000 <= addr < 0x2002_0000 or 0x1000_0000 <= addr < 0x1001_0000
        if typ == NOBITS:
            bss += size
        elif in_ram:
            data += size
            flash += size  # load image
        elif typ == PROGBITS:
            flash += size
    ram = data + bss
    print(f"flash {flash} B ({flash / 1024:.1f} KiB), static RAM {ram} B ({ram / 1024:.1f} KiB; .data {data} + .bss {bss})")
    over = (lim["--flash-max"] is not None and flash > lim["--flash-max"]) or (
        lim["--ram-max"] is not None and ram > lim["--ram-max"])
    sys.exit(1 if over else 0)


if __name__ == "__main__":
    main()
