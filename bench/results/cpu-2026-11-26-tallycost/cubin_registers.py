import struct, sys
ATTR = {0x2f: "REGCOUNT", 0x11: "FRAME_SIZE", 0x12: "MIN_STACK_SIZE", 0x23: "MAX_STACK_SIZE"}
def sections(b):
    shoff, = struct.unpack_from("<Q", b, 0x28); shentsize, shnum, shstrndx = struct.unpack_from("<HHH", b, 0x3a)
    hdrs = [struct.unpack_from("<IIQQQQIIQQ", b, shoff + i * shentsize) for i in range(shnum)]
    strtab = hdrs[shstrndx]
    name = lambda off: b[strtab[4] + off: b.index(b"\0", strtab[4] + off)].decode()
    return {name(h[0]): b[h[4]: h[4] + h[5]] for h in hdrs}
for path in sys.argv[1:]:
    b = open(path, "rb").read(); secs = sections(b)
    out = {}
    for sname, data in secs.items():
        if sname.startswith(".nv.local"): out["local_bytes"] = len(data)
        if sname == ".nv.info":
            i = 0
            while i < len(data):
                fmt, attr = data[i], data[i + 1]; i += 2
                if fmt == 4:
                    size, = struct.unpack_from("<H", data, i); i += 2
                    if attr in ATTR and size == 8:
                        out[ATTR[attr]] = struct.unpack_from("<II", data, i)[1]
                    i += size
                elif fmt == 3: i += 2
                elif fmt == 2: i += 1
    print(path.split("/")[-2], out)
