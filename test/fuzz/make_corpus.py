#!/usr/bin/env python3
"""Writes the seed corpus of the reader fuzzers into test/fuzz/corpus/FORMAT/.

Seeds are small valid meshes that reach every branch of a parser: data/'s meshes, and a
regular tetrahedron in every encoding lapmesh reads (OFF variants, OBJ with v/vt/vn and
relative indices, ASCII and binary PLY of both byte orders with several count and index
types and extra elements, ASCII and binary STL). Run it again after changing a parser's
grammar; the files are committed so the fuzzers start from them in CI.
"""
import os
import shutil
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
POINTS = [(1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1)]
FACES = [(0, 1, 2), (0, 3, 1), (0, 2, 3), (1, 3, 2)]


def write(fmt, name, data):
    d = os.path.join(HERE, "corpus", fmt)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def ply_header(fmt, vertex_props, face_list, extra=""):
    h = "ply\nformat %s 1.0\ncomment seed\nelement vertex 4\n" % fmt
    h += "".join("property %s %s\n" % p for p in vertex_props)
    h += extra
    h += "element face 4\nproperty list %s %s %s\nend_header\n" % face_list
    return h


def main():
    for fmt, names in (("off", ["tetrahedron.off", "flat_hexagon.off", "flipped_face.off", "bad_nonmanifold_edge.off"]),
                       ("obj", ["square_pyramid.obj"])):
        for n in names:
            os.makedirs(os.path.join(HERE, "corpus", fmt), exist_ok=True)
            shutil.copy(os.path.join(ROOT, "data", n), os.path.join(HERE, "corpus", fmt, n))

    verts = "".join("%g %g %g\n" % p for p in POINTS)
    tris = "".join("3 %d %d %d\n" % f for f in FACES)
    write("off", "counts_on_header.off", "OFF 4 4 0 # counts\n" + verts + tris)
    write("off", "coff_colours.off",
          "COFF\n4 4 6\n" + "".join("%g %g %g 255 0 0 255\n" % p for p in POINTS) +
          "".join("3 %d %d %d 0.5 0.5 0.5\n" % f for f in FACES))
    write("off", "quad.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")

    write("obj", "tetra_vt_vn.obj",
          "o tetra\n" + "".join("v %g %g %g\n" % p for p in POINTS) + "vt 0 0\nvn 0 0 1\ns off\n" +
          "".join("f %d/1/1 %d/1/1 %d/1/1\n" % tuple(i + 1 for i in f) for f in FACES[:2]) +
          "".join("f %d %d %d\n" % tuple(i - 4 for i in f) for f in FACES[2:]))

    write("ply", "ascii.ply", ply_header("ascii", [("float", "x"), ("float", "y"), ("float", "z")],
                                         ("uchar", "int", "vertex_indices")) + verts + tris)
    write("ply", "ascii_extra_element.ply",
          ply_header("ascii", [("double", "x"), ("double", "y"), ("double", "z"), ("uchar", "red")],
                     ("uint8", "uint32", "vertex_index"),
                     ) .replace("end_header\n", "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n") +
          "".join("%g %g %g 7\n" % p for p in POINTS) + tris + "0 1\n")
    for order, fmt in (("<", "binary_little_endian"), (">", "binary_big_endian")):
        body = b"".join(struct.pack(order + "fff", *p) for p in POINTS)
        body += b"".join(struct.pack(order + "Biii", 3, *f) for f in FACES)
        write("ply", "binary_%s_float_int.ply" % fmt.split("_")[1],
              ply_header(fmt, [("float", "x"), ("float", "y"), ("float", "z")], ("uchar", "int", "vertex_indices")).encode() + body)
        body = b"".join(struct.pack(order + "dddB", *p, 200) for p in POINTS)
        body += b"".join(struct.pack(order + "Bhhh", 3, *f) + struct.pack(order + "Hff", 2, 0.5, 0.25) for f in FACES)
        write("ply", "binary_%s_double_short.ply" % fmt.split("_")[1],
              ply_header(fmt, [("double", "x"), ("double", "y"), ("double", "z"), ("uchar", "alpha")],
                         ("uchar", "short", "vertex_indices")).replace(
                  "end_header\n", "property list ushort float texcoord\nend_header\n").encode() + body)

    def facet_normal(f):
        return "0 0 1"
    stl = "solid seed\n"
    for f in FACES:
        stl += "facet normal %s\nouter loop\n" % facet_normal(f)
        stl += "".join("vertex %g %g %g\n" % POINTS[i] for i in f)
        stl += "endloop\nendfacet\n"
    write("stl", "ascii.stl", stl + "endsolid seed\n")
    binary = b"binary seed".ljust(80, b" ") + struct.pack("<I", len(FACES))
    for f in FACES:
        binary += struct.pack("<3f", 0, 0, 1) + b"".join(struct.pack("<3f", *POINTS[i]) for i in f) + b"\0\0"
    write("stl", "binary.stl", binary)


if __name__ == "__main__":
    main()
