#!/usr/bin/env python3
"""Writes the hand-made seeds in fuzz/corpus/ (the small real meshes come from tests/data).

Run from anywhere: python3 fuzz/make_seeds.py. Standard library only; the output is
deterministic, so re-running it changes nothing.
"""
import io
import math
import os
import struct
import warnings
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
SHARED = os.path.join(HERE, "..", "..", "shared", "meshes")

TETRA = [((0, 0, 0), (0, 2, 0), (2, 0, 0)), ((0, 0, 0), (2, 0, 0), (0, 0, 2)),
         ((0, 0, 0), (0, 0, 2), (0, 2, 0)), ((2, 0, 0), (0, 2, 0), (0, 0, 2))]


def cube(size=10.0):
    c = [(x, y, z) for x in (0, size) for y in (0, size) for z in (0, size)]
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = []
    for a, b, cc, d in quads:
        tris += [(c[a], c[b], c[cc]), (c[a], c[cc], c[d])]
    return tris


def normal(t):
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t
    u = (bx - ax, by - ay, bz - az)
    v = (cx - ax, cy - ay, cz - az)
    n = (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])
    length = math.sqrt(sum(x * x for x in n)) or 1.0
    return tuple(x / length for x in n)


def binary(tris, header=b"stlrefine fuzz seed", count=None, trailing=b"", normals=None):
    out = header.ljust(80, b" ")[:80] + struct.pack("<I", len(tris) if count is None else count)
    for i, t in enumerate(tris):
        n = normals[i] if normals else normal(t)
        out += struct.pack("<3f", *n)
        for p in t:
            out += struct.pack("<3f", *p)
        out += b"\0\0"
    return out + trailing


def ascii_stl(tris, name="seed", fmt="{:e}", eol="\n", kw=str.lower, indent="  "):
    lines = [kw("solid") + (" " + name if name else "")]
    for t in tris:
        n = normal(t)
        lines.append(indent + kw("facet normal") + " " + " ".join(fmt.format(x) for x in n))
        lines.append(indent * 2 + kw("outer loop"))
        for p in t:
            lines.append(indent * 3 + kw("vertex") + " " + " ".join(fmt.format(x) for x in p))
        lines.append(indent * 2 + kw("endloop"))
        lines.append(indent + kw("endfacet"))
    lines.append(kw("endsolid") + (" " + name if name else ""))
    return (eol.join(lines) + eol).encode()


def write(sub, name, data):
    os.makedirs(os.path.join(HERE, "corpus", sub), exist_ok=True)
    with open(os.path.join(HERE, "corpus", sub, name), "wb") as f:
        f.write(data)


def zipped(entries, deflate=True):
    """A zip of (name, bytes) entries, dated 1980 so the output is deterministic; a name may
    repeat (the archive reader must refuse it)."""
    out = io.BytesIO()
    with warnings.catch_warnings(), zipfile.ZipFile(out, "w") as z:
        warnings.simplefilter("ignore")  # the duplicate name is the point of that seed
        for name, data in entries:
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED if deflate else zipfile.ZIP_STORED
            z.writestr(info, data)
    return out.getvalue()


def archive_seeds():
    """Zips of parts as a bureau uploads them (one job, one result per part), and the ones
    the archive reader refuses by name."""
    tetra, cube_stl = binary(TETRA), binary(cube())
    obj = b"v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
    seeds = {
        "two_parts.zip": [("a.stl", tetra), ("parts/b.STL", cube_stl)],
        "stored.zip": [("tetra.stl", tetra)],
        "mixed_formats.zip": [("t.stl", ascii_stl(TETRA)), ("t.obj", obj), ("dir/", b"")],
        "macos.zip": [("t.stl", tetra), ("__MACOSX/._t.stl", b"\0\5\26\7")],
        "duplicate.zip": [("t.stl", tetra), ("t.stl", tetra)],
        "dotdot.zip": [("../t.stl", tetra)],
        "backslash.zip": [("a\\t.stl", tetra)],
        "not_a_mesh.zip": [("t.stl", tetra), ("readme.txt", b"hello")],
        "nested.zip": [("inner.stl", zipped([("t.stl", tetra)]))],
        "empty_dir_only.zip": [("dir/", b"")],
        "ratio.zip": [("zeros.stl", bytes(65536))],
        "looks_3mf.zip": [("[Content_Types].xml", b"<Types/>"), ("3D/3dmodel.model", b"<model/>")],
    }
    for name, entries in seeds.items():
        write("archive", name, zipped(entries, deflate=name != "stored.zip"))


def main():
    archive_seeds()
    # Binary: the smallest parts, the edge cases of the size rule and the header.
    write("stl_binary", "tetra.stl", binary(TETRA))
    write("stl_binary", "one_facet.stl", binary(TETRA[:1]))
    write("stl_binary", "cube.stl", binary(cube()))
    write("stl_binary", "solid_header.stl", binary(TETRA, header=b"solid tetra"))
    write("stl_binary", "trailing_3.stl", binary(TETRA, trailing=b"\0\0\0"))
    write("stl_binary", "count_high.stl", binary(TETRA, count=5))
    write("stl_binary", "nan_normals.stl",
          binary(TETRA, normals=[(float("nan"),) * 3] * len(TETRA)))
    write("stl_binary", "zero_count.stl", binary([], count=0))
    write("stl_binary", "large_coords.stl",
          binary([tuple(tuple(c * 4.9e8 for c in p) for p in t) for t in TETRA]))

    # ASCII: exporters' styles (SolidWorks %e, OpenSCAD %g, CRLF, BOM, upper case), several
    # solids, number spellings the reader must take or refuse precisely.
    write("stl_ascii", "tetra.stl", ascii_stl(TETRA, name="tetra"))
    write("stl_ascii", "cube_g.stl", ascii_stl(cube(), name="OpenSCAD_Model", fmt="{:g}"))
    write("stl_ascii", "cube_crlf_bom_upper.stl",
          b"\xef\xbb\xbf" + ascii_stl(cube(), name="PART", eol="\r\n", kw=str.upper, indent="\t"))
    write("stl_ascii", "two_solids.stl",
          ascii_stl(TETRA[:2], name="a") + ascii_stl(TETRA[2:], name="b"))
    write("stl_ascii", "no_name.stl", ascii_stl(TETRA, name=""))
    write("stl_ascii", "numbers.stl", b"""solid numbers
facet normal -1.#IND00 nan +1.0e+00
outer loop
vertex +1.0e+00 -0 1e-50
vertex .5 0x1 1E2
vertex 3.4028235e38 -1e999 0
endloop
endfacet
endsolid numbers
""")
    write("stl_ascii", "quad.stl", b"""solid quad
facet normal 0 0 1
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 1 1 0
vertex 0 1 0
endloop
endfacet
endsolid quad
""")
    write("stl_ascii", "missing_endsolid.stl", ascii_stl(TETRA, name="t")[:-len(b"endsolid t\n")])
    gear = os.path.join(SHARED, "malformed", "gearwheel_ascii.stl")
    if os.path.exists(gear):  # a real exporter's text: its first 24 facets, closed
        with open(gear, "rb") as f:
            lines = f.read().splitlines(keepends=True)
        write("stl_ascii", "gearwheel_head.stl", b"".join(lines[:1 + 7 * 24]) + lines[-1])

    # The binary meshes of ../shared/meshes (not large/), each cut to its first facets so
    # that it fits -max_len (16 KiB: 326 facets) with the header count made to match: real
    # exporters' headers, attribute bytes, float patterns and connectivity. Files already in
    # tests/data (read whole by run.sh) are left out; two heads are also written as ASCII.
    if os.path.isdir(SHARED):
        copied = set()
        for sub in ("core", "malformed"):
            for name in os.listdir(os.path.join(HERE, "..", "tests", "data", sub)):
                copied.add(name)
        for sub in ("cad", "generated", "organic", "malformed"):
            for name in sorted(os.listdir(os.path.join(SHARED, sub))):
                if not name.endswith(".stl") or name in copied or name == "gearwheel_ascii.stl":
                    continue
                with open(os.path.join(SHARED, sub, name), "rb") as f:
                    data = f.read()
                n = min(struct.unpack_from("<I", data, 80)[0], (len(data) - 84) // 50, 326)
                head = data[:80] + struct.pack("<I", n) + data[84:84 + 50 * n]
                write("shared_meshes", f"{sub}_{name[:-4]}_{n}.stl", head)
                if name in ("bunny_low.stl", "bracket.stl"):
                    tris = [[struct.unpack_from("<3f", head, 84 + 50 * i + 12 * (1 + k))
                             for k in range(3)] for i in range(48)]
                    write("stl_ascii", f"{name[:-4]}_head48.stl",
                          ascii_stl(tris, name=name[:-4], fmt="{:.6e}"))

    # Query strings of every route: valid ones, and the spellings a parser must refuse.
    queries = {
        "refine_default": "scheme=butterfly&levels=2",
        "refine_unified": "scheme=sqrt3-unified&levels=3&alpha=0.5&alpha_features=1"
                          "&crease_angle=30&max_faces=100000",
        "refine_adaptive": "scheme=lsf&adaptive_tol=0.01&max_level=4&weld_tolerance=0.001",
        "refine_adaptive_sqrt3": "scheme=sqrt3-interp&adaptive_angle=20&adaptive_tol=0.05"
                                 "&max_level=3",
        "refine_slice": "scheme=loop&levels=2&slice=0.1&slice_format=cli-binary",
        "refine_threads": "scheme=sqrt3-interp&levels=1&threads=2",
        "slice_uniform": "layer_height=0.2&format=svg&z_min=0&z_max=10&max_layers=100",
        "slice_heights": "heights=0.1,0.2,%200.35&format=cli-ascii",
        "info": "crease_angle=35&weld_tolerance=0",
        "bad_numbers": "levels=1e400&crease_angle=nan&max_faces=-1&alpha=0x1p3",
        "duplicates": "levels=1&levels=2&scheme=loop&scheme=loop",
        "encoded": "sch%65me=b%75tterfly&levels=%32&z_max=+1&heights=1%2C2",
    }
    for name, q in queries.items():
        write("query", name, q.encode())


if __name__ == "__main__":
    main()
