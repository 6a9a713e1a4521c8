#!/usr/bin/env python3
"""Independent PLY reader (standard library only) used by the tests to check photomill's
binary PLY output: prints each vertex's properties in file order, floats with repr()."""
import struct
import sys

TYPES = {"char": "b", "int8": "b", "uchar": "B", "uint8": "B", "short": "h", "int16": "h",
         "ushort": "H", "uint16": "H", "int": "i", "int32": "i", "uint": "I", "uint32": "I",
         "float": "f", "float32": "f", "double": "d", "float64": "d"}

def main(path):
    with open(path, "rb") as f:
        assert f.readline().strip() == b"ply"
        props, count, fmt = [], 0, None
        while True:
            words = f.readline().decode("ascii").split()
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                assert words[1] == "vertex"
                count = int(words[2])
            elif words[0] == "property":
                props.append(TYPES[words[1]])
            elif words[0] == "end_header":
                break
        assert fmt == "binary_little_endian"
        record = struct.Struct("<" + "".join(props))
        for _ in range(count):
            values = record.unpack(f.read(record.size))
            print(" ".join(repr(float(v)) if isinstance(v, float) else str(v) for v in values))

if __name__ == "__main__":
    main(sys.argv[1])
