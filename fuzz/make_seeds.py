#!/usr/bin/env python3
"""Writes the seed corpus fuzz/corpus/<reader>/ (committed; run by hand when the formats
change): small valid inputs from data/sample and a few made here (glTF/GLB, 16-bit PNG
terrain, tiny spaces), each a few KB. Multi-file inputs are joined by the separator line of
fuzz/fuzz_support.h. The results JSON seeds of `diff` come from real bakes of the tiny
spaces, and the `plan` seeds from real plans of data/sample and a tiny space, so the path of
a built shadowcull is needed for them; readers named after it limit what is rewritten:

    fuzz/make_seeds.py [build/bin/shadowcull [READER ...]]

The glTF seeds of EXT_meshopt_compression are made with Debian's libmeshoptimizer (through
ctypes) and gltfpack; without them those seeds are kept as they are.
"""
import base64
import ctypes
import ctypes.util
import json
import pathlib
import shutil
import struct
import subprocess
import sys
import tempfile
import zlib

ROOT = pathlib.Path(__file__).resolve().parent.parent
SAMPLE = ROOT / "data" / "sample"
CORPUS = ROOT / "fuzz" / "corpus"
SEP = b"\n--- next file ---\n"  # kFuzzSeparator


def join(*parts):
    return SEP.join(p if isinstance(p, bytes) else p.encode() for p in parts)


def sample(path):
    return (SAMPLE / path).read_bytes()


def png16(n, values):
    """A 16-bit grey n x n PNG with the given row-major samples."""
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = b"".join(b"\0" + b"".join(struct.pack(">H", values[j * n + i]) for i in range(n)) for j in range(n))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", n, n, 16, 0, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))


def terrain_xml(png, lo, hi):
    return f"<terrain>\n  <heights> {png} </heights>\n  <minHeight> {lo} </minHeight>\n  <maxHeight> {hi} </maxHeight>\n</terrain>\n"


# ---------------------------------------------------------------------------------------
# glTF

class Gltf:
    """One buffer, views, accessors, meshes and nodes, as tests/mesh_gltf_test.cpp builds them."""

    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": [], "meshes": [], "nodes": []}

    def view(self, data, stride=0):
        while len(self.bin) % 4:
            self.bin.append(0)
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            v["byteStride"] = stride
        self.bin += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, view, component, count, kind):
        self.doc["accessors"].append({"bufferView": view, "componentType": component, "count": count, "type": kind})
        return len(self.doc["accessors"]) - 1

    def positions(self, points):
        return self.accessor(self.view(b"".join(struct.pack("<3f", *p) for p in points)), 5126, len(points), "VEC3")

    def indices(self, ix, component=5125):
        fmt = {5121: "<B", 5123: "<H", 5125: "<I"}[component]
        return self.accessor(self.view(b"".join(struct.pack(fmt, i) for i in ix)), component, len(ix), "SCALAR")

    extra_buffers = []  # after buffer 0, e.g. an EXT_meshopt_compression fallback buffer

    def gltf(self, uri=None):
        d = dict(self.doc)
        d["buffers"] = [{"byteLength": len(self.bin),
                         "uri": uri or "data:application/octet-stream;base64," + base64.b64encode(bytes(self.bin)).decode()}]
        d["buffers"] += self.extra_buffers
        return json.dumps(d, indent=1).encode()

    def glb(self):
        d = dict(self.doc)
        d["buffers"] = [{"byteLength": len(self.bin)}] + self.extra_buffers
        text = json.dumps(d).encode()
        text += b" " * (-len(text) % 4)
        data = bytes(self.bin) + b"\0" * (-len(self.bin) % 4)
        body = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(data), 0x004E4942) + data
        return b"glTF" + struct.pack("<II", 2, 12 + len(body)) + body


TRI = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def gltf_triangle():
    g = Gltf()
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": g.positions(TRI)}}]})
    g.doc["nodes"].append({"mesh": 0, "translation": [1, 2, 3], "rotation": [0, 0.7071, 0, 0.7071], "scale": [2, 2, -2]})
    g.doc["scenes"] = [{"nodes": [0]}]
    return g


def gltf_three_primitives():
    g = Gltf()
    tri, quad = g.positions(TRI), g.positions(QUAD)
    g.doc["materials"] = [{"alphaMode": "MASK"}, {"doubleSided": True}]
    g.doc["meshes"].append({"primitives": [
        {"attributes": {"POSITION": tri}, "indices": g.indices([0, 1, 2], 5121), "material": 0},
        {"attributes": {"POSITION": quad}, "indices": g.indices([0, 1, 2, 0, 2, 3], 5123), "material": 1}]})
    g.doc["meshes"].append({"primitives": [
        {"attributes": {"POSITION": quad}, "indices": g.indices([0, 1, 2, 3]), "mode": 5},
        {"attributes": {"POSITION": quad}, "mode": 6}]})
    g.doc["nodes"] = [{"mesh": 1, "children": [1]},
                      {"mesh": 0, "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 5, 0, 0, 1]}]
    g.doc["scenes"] = [{"nodes": [0]}]
    g.doc["scene"] = 0
    return g


def gltf_strided():
    g = Gltf()
    data = b"".join(struct.pack("<3f", *p) + b"\0" * 4 for p in QUAD)  # 16-byte stride
    pos = g.accessor(g.view(data, 16), 5126, 4, "VEC3")
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": pos}, "indices": g.indices([0, 1, 2, 0, 2, 3])}]})
    g.doc["nodes"].append({"mesh": 0})
    return g


def gltf_quantized():
    """KHR_mesh_quantization: unnormalized UNSIGNED_SHORT positions dequantized by the node
    (as gltfpack writes them), normalized BYTE and SHORT positions, 4- and 8-byte strides."""
    g = Gltf()
    ushort = g.accessor(g.view(b"".join(struct.pack("<4H", *p, 0) for p in [(0, 0, 0), (16383, 0, 0), (0, 16383, 0)]), 8),
                        5123, 3, "VEC3")
    byte = g.accessor(g.view(b"".join(struct.pack("<4b", *p, 0) for p in [(-128, 0, 0), (127, 0, 0), (127, 127, -5)]), 4),
                      5120, 3, "VEC3")
    g.doc["accessors"][byte]["normalized"] = True
    short = g.accessor(g.view(b"".join(struct.pack("<4h", *p, 0) for p in [(0, 0, 0), (32767, 0, 0), (0, -32767, 100)]), 8),
                       5122, 3, "VEC3")
    g.doc["accessors"][short]["normalized"] = True
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": ushort}}]})
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": byte}, "indices": g.indices([0, 1, 2], 5121)},
                                           {"attributes": {"POSITION": short}}]})
    s = 2 / 16383
    g.doc["nodes"] = [{"mesh": 0, "translation": [-1, 0, 2], "scale": [s, s, s]}, {"mesh": 1}]
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["KHR_mesh_quantization"]
    return g


def gltf_sparse():
    """Sparse accessors: positions over a base view (UNSIGNED_BYTE indices), indices over a
    base view (UNSIGNED_SHORT indices), positions without a bufferView (UNSIGNED_INT indices)."""
    g = Gltf()
    pos = g.positions(QUAD)
    g.doc["accessors"][pos]["sparse"] = {
        "count": 2, "indices": {"bufferView": g.view(bytes([1, 3])), "componentType": 5121},
        "values": {"bufferView": g.view(struct.pack("<6f", 1, 0, 1, 0, 1, 1))}}
    ix = g.indices([0, 1, 2, 0, 2, 2], 5123)
    g.doc["accessors"][ix]["sparse"] = {
        "count": 1, "indices": {"bufferView": g.view(struct.pack("<H", 5)), "componentType": 5123},
        "values": {"bufferView": g.view(struct.pack("<H", 3))}}
    g.doc["accessors"].append({"componentType": 5126, "count": 3, "type": "VEC3", "sparse": {
        "count": 2, "indices": {"bufferView": g.view(struct.pack("<2I", 1, 2)), "componentType": 5125},
        "values": {"bufferView": g.view(struct.pack("<6f", 1, 0, 0, 0, 1, 0)), "byteOffset": 0}}})
    zeros = len(g.doc["accessors"]) - 1
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": pos}, "indices": ix},
                                           {"attributes": {"POSITION": zeros}}]})
    g.doc["nodes"].append({"mesh": 0})
    return g


def meshoptimizer():
    """Debian's libmeshoptimizer through ctypes, or None."""
    name = ctypes.util.find_library("meshoptimizer")
    if not name:
        return None
    lib = ctypes.CDLL(name)
    size_t, p = ctypes.c_size_t, ctypes.c_void_p
    for f, args in {"meshopt_encodeVertexBuffer": [p, size_t, p, size_t, size_t], "meshopt_encodeVertexBufferBound": [size_t, size_t],
                    "meshopt_encodeIndexBuffer": [p, size_t, p, size_t], "meshopt_encodeIndexBufferBound": [size_t, size_t],
                    "meshopt_encodeIndexSequence": [p, size_t, p, size_t], "meshopt_encodeIndexSequenceBound": [size_t, size_t]}.items():
        getattr(lib, f).argtypes = args
        getattr(lib, f).restype = size_t
    lib.meshopt_encodeFilterExp.argtypes = [p, size_t, size_t, ctypes.c_int, p]
    lib.meshopt_encodeFilterExp.restype = None
    return lib


def gltf_meshopt_filters(lib):
    """EXT_meshopt_compression made with libmeshoptimizer: float positions with the
    EXPONENTIAL filter (ATTRIBUTES), a triangle list (TRIANGLES, 16-bit) and a strip
    (INDICES, 32-bit); the views on a fallback buffer without data."""
    g = Gltf()
    fallback = [0]

    def compressed(raw, count, stride, mode, filter=None):
        if mode == "ATTRIBUTES":
            out = ctypes.create_string_buffer(lib.meshopt_encodeVertexBufferBound(count, stride))
            n = lib.meshopt_encodeVertexBuffer(out, len(out), raw, count, stride)
        else:
            ix = (ctypes.c_uint * count)(*[int.from_bytes(raw[k * stride:(k + 1) * stride], "little") for k in range(count)])
            bound = getattr(lib, "meshopt_encodeIndexBufferBound" if mode == "TRIANGLES" else "meshopt_encodeIndexSequenceBound")
            encode = getattr(lib, "meshopt_encodeIndexBuffer" if mode == "TRIANGLES" else "meshopt_encodeIndexSequence")
            out = ctypes.create_string_buffer(bound(count, max(ix) + 1))
            n = encode(out, len(out), ix, count)
        while len(g.bin) % 4:
            g.bin.append(0)
        ext = {"buffer": 0, "byteOffset": len(g.bin), "byteLength": n, "byteStride": stride, "count": count, "mode": mode}
        if filter:
            ext["filter"] = filter
        g.bin += out.raw[:n]
        v = {"buffer": 1, "byteOffset": fallback[0], "byteLength": count * stride, "extensions": {"EXT_meshopt_compression": ext}}
        if mode == "ATTRIBUTES":
            v["byteStride"] = stride
        fallback[0] += (count * stride + 3) // 4 * 4
        g.doc["bufferViews"].append(v)
        return len(g.doc["bufferViews"]) - 1

    floats = [c for p in QUAD for c in p]
    encoded = ctypes.create_string_buffer(len(floats) * 4)
    lib.meshopt_encodeFilterExp(encoded, len(QUAD), 12, 15, (ctypes.c_float * len(floats))(*floats))
    pos = g.accessor(compressed(encoded.raw, len(QUAD), 12, "ATTRIBUTES", "EXPONENTIAL"), 5126, len(QUAD), "VEC3")
    tri = g.accessor(compressed(struct.pack("<6H", 0, 1, 2, 0, 2, 3), 6, 2, "TRIANGLES"), 5123, 6, "SCALAR")
    strip = g.accessor(compressed(struct.pack("<4I", 0, 1, 3, 2), 4, 4, "INDICES"), 5125, 4, "SCALAR")
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": pos}, "indices": tri},
                                           {"attributes": {"POSITION": pos}, "indices": strip, "mode": 5}]})
    g.doc["nodes"].append({"mesh": 0})
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["EXT_meshopt_compression"]
    g.extra_buffers = [{"byteLength": fallback[0], "extensions": {"EXT_meshopt_compression": {"fallback": True}}}]
    return g


# A 5 x 4 wavy grid (20 points, 24 faces, POSITION unique id 0) as libdraco 1.5.5's encoder
# writes it (edgebreaker, speed 0, 12-bit positions); kept as bytes since Python has no
# Draco encoder here.
DRACO_GRID = bytes.fromhex(
    "445241434f02020101000000141800180300085ff7f4a96af5a902ff011101ff000101000903000002010101000d0395"
    "2913350303350369066906350307effc2cc899ff8001f8ff28d2ffff63c7ff00b80e020020404002c013001000000102"
    "00b01d100000000000ff0f000000000000000000005f7d68be000080400c")


def gltf_draco():
    """KHR_draco_mesh_compression: the primitive's accessors state the decoded counts."""
    g = Gltf()
    view = g.view(DRACO_GRID)
    g.doc["accessors"] = [{"componentType": 5126, "count": 20, "type": "VEC3"},
                          {"componentType": 5125, "count": 72, "type": "SCALAR"}]
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "extensions": {
        "KHR_draco_mesh_compression": {"bufferView": view, "attributes": {"POSITION": 0}}}}]})
    g.doc["nodes"].append({"mesh": 0})
    g.doc["extensionsUsed"] = g.doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    return g


def gltfpack(g, *flags):
    """What gltfpack (Debian package gltfpack) makes of `g`, as GLB bytes; None without it."""
    if not shutil.which("gltfpack"):
        return None
    with tempfile.TemporaryDirectory() as t:
        tmp = pathlib.Path(t)
        (tmp / "in.gltf").write_bytes(g.gltf())
        subprocess.run(["gltfpack", "-i", str(tmp / "in.gltf"), "-o", str(tmp / "out.glb"), *flags],
                       check=True, stdout=subprocess.DEVNULL)
        return (tmp / "out.glb").read_bytes()


# ---------------------------------------------------------------------------------------
# Tiny spaces for the bake (and, baked, for diff)

def space_xml(lights, extra=""):
    return f"<space>\n  <chunkSize> 100 </chunkSize>\n  <neighbours> 1 </neighbours>\n{extra}{lights}</space>\n"


SUN = "  <light> <name> sun </name> <type> directional </type> <direction> 0.3 -1 0.2 </direction> <bias> 0.05 </bias> </light>\n"
LAMP = "  <light> <name> lamp </name> <type> point </type> <position> 52 4 50 </position> <range> 25 </range> </light>\n"
TORCH = ("  <light> <name> torch </name> <type> spot </type> <position> 50 8 50 </position> <direction> 0 -1 0 </direction>"
         " <range> 20 </range> <coneAngle> 30 </coneAngle> <slopeBias> 0.1 </slopeBias> </light>\n")


def model(resource, x, y, z, uuid, extra=""):
    return (f"  <model>\n    <resource> {resource} </resource>\n    <uuid> {uuid} </uuid>\n    <transform>\n"
            f"      <row0> 1 0 0 </row0>\n      <row1> 0 1 0 </row1>\n      <row2> 0 0 1 </row2>\n"
            f"      <row3> {x} {y} {z} </row3>\n    </transform>\n{extra}  </model>\n")


def chunk(*objects):
    return "<chunk>\n" + "".join(objects) + "</chunk>\n"


TERRAIN = "  <terrain>\n    <resource> t.terrain </resource>\n  </terrain>\n"
FLAT3 = png16(3, [0, 1000, 0, 2000, 3000, 1000, 0, 500, 0])


def bakes():
    # No MTL in a bake's input: the crate without its mtllib and usemtl lines (one group).
    crate = b"".join(l for l in sample("models/crate.obj").splitlines(True) if not l.startswith((b"mtllib", b"usemtl")))
    return {
        "cube_on_terrain": [space_xml(SUN + LAMP), chunk(model("m.obj", 50, 0.2, 50, "A-1"), TERRAIN),
                            chunk(model("m.obj", 10, 3, 40, "B-1")), crate, terrain_xml("t.png", 0, 1), FLAT3],
        "spot_noncaster": [space_xml(TORCH, "  <terrainTolerance> 0.5 </terrainTolerance>\n"),
                           chunk(model("m.obj", 50, 0, 50, "A-1", "    <castsShadow> false </castsShadow>\n"),
                                 model("m.obj", 52, 2, 50, "A-2"), TERRAIN),
                           "<chunk/>\n", crate, terrain_xml("t.png", -1, 2), FLAT3],
        "floating_skipped": [space_xml(SUN, '  <neighbours left="0" right="1" top="0" bottom="0"/>\n'),
                             chunk(model("m.obj", 40, 20, 50, "A-1"), model("missing.obj", 45, 20, 50, "A-2")),
                             chunk(model("m.obj", 5, 20, 50, "B-1")), crate],
    }


def results(shadowcull, parts, tmp, name):
    space = tmp / name
    space.mkdir()
    for file, part in zip(["space.xml", "00000000o.chunk", "00010000o.chunk", "m.obj", "t.terrain", "t.png"], parts):
        (space / file).write_bytes(part if isinstance(part, bytes) else part.encode())
    out = tmp / (name + ".json")
    subprocess.run([shadowcull, "bake", str(space), "--dry-run", "--quiet", "--threads", "1", "--samples", "16",
                    "--stages", "raycast,geometry", "--results", str(out)], check=False)
    # Compact: the same content in fewer bytes for the fuzzer to work through.
    return json.dumps(json.loads(out.read_bytes().replace(str(tmp).encode(), b"SPACE")), separators=(",", ":")).encode()


# ---------------------------------------------------------------------------------------
# Sharded bake plans (fuzz_plan.cpp: the --shard argument, plan.json, the shard's file,
# inputs.json; "$SAMPLE", "$SETTINGS" and "$PLAN" stand for what depends on the checkout)

def plan_files(shadowcull, space, shards, tmp):
    out = tmp / "plan"
    shutil.rmtree(out, ignore_errors=True)
    # Exit 1 is a plan made with warnings (the tiny space's missing resource).
    done = subprocess.run([shadowcull, "plan", str(space), "--shards", str(shards), "--plan", str(out), "--quiet"],
                          stderr=subprocess.DEVNULL)
    if done.returncode not in (0, 1):
        raise RuntimeError(f"shadowcull plan {space} failed ({done.returncode})")
    return out


def plan_seed(out, index, shards, space, token, head_edit=lambda h: h):
    def read(name):
        return json.loads((out / name).read_text())

    def compact(doc):
        return json.dumps(doc, separators=(",", ":")).replace(str(space), token)

    head = head_edit(read("plan.json"))
    shard = read(f"shard-{index}-of-{shards}.json")
    shard["plan"] = "$PLAN"
    inputs = read("inputs.json")
    inputs["plan"] = "$PLAN"
    inputs["files"] = inputs["files"][:3]  # the list is not looked into: a few names keep the seed small
    return join(f"{index}/{shards}", compact(head), compact(shard), compact(inputs))


def plans(shadowcull, tmp):
    seeds = {}
    sample_plan = lambda h: dict(h, settings="$SETTINGS")
    for shards, index in [(4, 1), (4, 4), (1, 1)]:
        out = plan_files(shadowcull, SAMPLE, shards, tmp)
        seeds[f"sample_{index}_of_{shards}.plan"] = plan_seed(out, index, shards, SAMPLE, "$SAMPLE", sample_plan)
    # A tiny space with a warning (an object whose resource is missing): plan.json's warnings.
    space = tmp / "warnings"
    space.mkdir()
    crate = bakes()["cube_on_terrain"][3]
    files = {"space.xml": space_xml(SUN), "00000000o.chunk": chunk(model("m.obj", 40, 20, 50, "A-1"),
                                                                   model("missing.obj", 45, 20, 50, "A-2")),
             "00010000o.chunk": chunk(model("m.obj", 5, 20, 50, "B-1")), "m.obj": crate}
    for file, part in files.items():
        (space / file).write_bytes(part if isinstance(part, bytes) else part.encode())
    seeds["warnings_2_of_2.plan"] = plan_seed(plan_files(shadowcull, space, 2, tmp), 2, 2, space, "SPACE")
    return seeds


# ---------------------------------------------------------------------------------------

def main():
    seeds = {"space": {}, "chunk": {}, "model": {}, "obj": {}, "gltf": {}, "terrain": {}, "diff": {}, "bake": {},
             "plan": {}}

    seeds["space"]["sample.xml"] = sample("space.xml")
    seeds["space"]["sides_root.xml"] = space_xml(
        TORCH + LAMP, '  <neighbours left="2" right="0" top="1" bottom="3"/>\n  <resourceRoot> res </resourceRoot>\n'
        "  <terrainTolerance> 0.25 </terrainTolerance>\n  <unknown> kept </unknown>\n")
    seeds["space"]["empty.xml"] = "<space/>\n"

    for name in ["00000000o.chunk", "ffff0000o.chunk"]:
        seeds["chunk"]["sample_" + name] = sample(name)
    small = chunk(model("m.obj", 1.5, -2, 3e-3, "U-1", "    <castsShadow> 0 </castsShadow>\n"
                        "    <shadow> 3\n      <RenderSet>\n        <Geometry>\n          <PrimitiveGroup> 3 </PrimitiveGroup>\n"
                        "        </Geometry>\n      </RenderSet>\n    </shadow>\n    <shadow> 1 </shadow>\n"),
                  "  <!-- comment -->\n  <other><model> nested </model></other>\n", TERRAIN)
    seeds["chunk"]["shadows.chunk"] = small
    seeds["chunk"]["crlf.chunk"] = small.replace("\n", "\r\n")

    for name in ["crate", "sign", "tree", "house", "rock_a"]:
        seeds["obj"][name + ".obj"] = join(sample(f"models/{name}.obj"), sample(f"models/{name}.mtl"))
    seeds["obj"]["refs.obj"] = join(
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0 1\nv 0 1 0 0.5 0.5 0.5\nvt 0 0\nvn 0 0 1\n"
        "f 1 2 3\nusemtl a\nf -4/1/1 -3/1/1 -2//1 \\\n -1\ng g\ns off\nusemtl\nf 1/1 3/1 4/1\nusemtl b c\nf 2 3 4\n",
        "newmtl a\nmap_d a.png\nnewmtl b c\nd 0.5\n")

    seeds["model"]["sign.model"] = join(sample("models/sign.model").replace(b"sign.obj", b"m.obj"),
                                        sample("models/sign.obj").replace(b"sign.mtl", b"m.mtl"), sample("models/sign.mtl"))
    seeds["model"]["gltf.model"] = join(
        '<model>\n  <visual> m.gltf </visual>\n  <primitiveGroup index="0" alphaTest="false" doubleSided="1"/>\n'
        '  <primitiveGroup index="2" alphaTest="true"/>\n</model>\n', "", "", gltf_three_primitives().gltf())

    seeds["gltf"]["triangle.gltf"] = gltf_triangle().gltf()
    seeds["gltf"]["three_primitives.glb"] = gltf_three_primitives().glb()
    external = gltf_three_primitives()
    seeds["gltf"]["external.gltf"] = join(external.gltf("b.bin"), bytes(external.bin))
    seeds["gltf"]["strided.glb"] = gltf_strided().glb()
    seeds["gltf"]["quantized.gltf"] = gltf_quantized().gltf()
    seeds["gltf"]["sparse.glb"] = gltf_sparse().glb()
    seeds["gltf"]["draco.glb"] = gltf_draco().glb()
    # Made with libmeshoptimizer and gltfpack; without them, kept as they are.
    lib = meshoptimizer()
    made = {"meshopt_filters.glb": gltf_meshopt_filters(lib).glb() if lib else None,
            "gltfpack_c.glb": gltfpack(gltf_three_primitives(), "-c"),
            "gltfpack_cf_vpn.glb": gltfpack(gltf_three_primitives(), "-cf", "-vpn")}
    for name, data in made.items():
        old = CORPUS / "gltf" / name
        if data is None:
            print(f"no libmeshoptimizer or gltfpack: {name} left as it is", file=sys.stderr)
            data = old.read_bytes() if old.exists() else None
        if data is not None:
            seeds["gltf"][name] = data

    seeds["terrain"]["small.terrain"] = join(terrain_xml("h.png", -10, 20), FLAT3)
    seeds["terrain"]["flat2.terrain"] = join(terrain_xml("h.png", 5, 5), png16(2, [0, 0, 0, 0]))
    seeds["terrain"]["sample.terrain"] = join(sample("terrain/00000000.terrain").replace(b"00000000.png", b"h.png"),
                                              sample("terrain/00000000.png"))

    for name, parts in bakes().items():
        seeds["bake"][name] = join(*parts)

    only = set(sys.argv[2:])
    if len(sys.argv) > 1 and (not only or "plan" in only):
        with tempfile.TemporaryDirectory() as t:
            seeds["plan"] = plans(sys.argv[1], pathlib.Path(t))
    if len(sys.argv) > 1 and (not only or "diff" in only):
        with tempfile.TemporaryDirectory() as t:
            tmp = pathlib.Path(t)
            b = bakes()
            a = results(sys.argv[1], b["cube_on_terrain"], tmp, "a")
            moved = list(b["cube_on_terrain"])
            moved[0] = moved[0].replace("52 4 50", "40 4 45").replace("0.3 -1 0.2", "-0.2 -1 0.1")
            seeds["diff"]["changed.json"] = join(a, results(sys.argv[1], moved, tmp, "b"))
            seeds["diff"]["skipped_same.json"] = results(sys.argv[1], b["floating_skipped"], tmp, "c")
    if len(sys.argv) < 2:
        print("no shadowcull given: diff and plan seeds left as they are", file=sys.stderr)

    for reader, files in seeds.items():
        if not files or (only and reader not in only):
            continue
        d = CORPUS / reader
        shutil.rmtree(d, ignore_errors=True)
        d.mkdir(parents=True)
        for name, data in files.items():
            (d / name).write_bytes(data if isinstance(data, bytes) else data.encode())


if __name__ == "__main__":
    main()
