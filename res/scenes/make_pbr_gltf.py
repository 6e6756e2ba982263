#!/usr/bin/env python3
"""Writes res/scenes/pbr-shelf.gltf: a small glTF 2.0 scene for Lucent's
snapshot tests, every byte made here (no third-party data).

It exercises what the glTF importer reads: a node hierarchy with TRS and
matrix transforms, a mesh instanced by two nodes, metallic-roughness
materials, a base colour texture with KHR_texture_transform and a
mirrored-repeat sampler, a normal map without tangents (MikkTSpace), a
double-sided emissive panel with KHR_materials_emissive_strength, a
KHR_lights_punctual spot light and a perspective camera. Buffers and
images are base64 data URIs, so the file stands alone.

Run: python3 res/scenes/make_pbr_gltf.py
"""
import base64, json, math, struct, zlib, os

def png(w, h, rows):
    """RGB8 PNG from rows of (r, g, b) tuples."""
    raw = b"".join(b"\0" + bytes(c for px in row for c in px) for row in rows)
    def chunk(t, d):
        return struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b""))

def uri(data, mime):
    return f"data:{mime};base64," + base64.b64encode(data).decode()

blob = bytearray()
views, accessors = [], []

def add(values, fmt, comps, ctype, target, minmax=False):
    while len(blob) % 4:
        blob.append(0)
    start = len(blob)
    for v in values:
        blob.extend(struct.pack("<" + fmt * comps, *(v if comps > 1 else (v,))))
    views.append({"buffer": 0, "byteOffset": start, "byteLength": len(blob) - start, "target": target})
    acc = {"bufferView": len(views) - 1, "componentType": ctype, "count": len(values),
           "type": {1: "SCALAR", 2: "VEC2", 3: "VEC3"}[comps]}
    if minmax:
        acc["min"] = [min(v[i] for v in values) for i in range(comps)]
        acc["max"] = [max(v[i] for v in values) for i in range(comps)]
    accessors.append(acc)
    return len(accessors) - 1

# Ground quad in xz, facing +y, as a triangle strip (u16 indices).
gp = [(-2, 0, 2), (2, 0, 2), (-2, 0, -2), (2, 0, -2)]
ground = {
    "POSITION": add(gp, "f", 3, 5126, 34962, True),
    "NORMAL": add([(0, 1, 0)] * 4, "f", 3, 5126, 34962),
    "TEXCOORD_0": add([(0, 1), (1, 1), (0, 0), (1, 0)], "f", 2, 5126, 34962),
}
ground_idx = add([0, 1, 2, 3], "H", 1, 5123, 34963)

# Unit cube, 24 vertices, u8 indices.
cp, cn = [], []
for axis in range(3):
    for s in (1, -1):
        n = [0, 0, 0]; n[axis] = s
        u = [0, 0, 0]; u[(axis + 1) % 3] = 1
        v = [0, 0, 0]; v[(axis + 2) % 3] = 1
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            cp.append(tuple(0.5 * (n[i] + a * u[i] + b * v[i]) for i in range(3)))
            cn.append(tuple(n))
ci = []
for f in range(6):
    q = [4 * f + k for k in range(4)]
    flip = f % 2 == 1
    tris = [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
    # Counter-clockwise seen from outside.
    n = cn[4 * f]
    for t in tris:
        a, b, c = (cp[i] for i in t)
        cr = [(b[(i+1)%3]-a[(i+1)%3])*(c[(i+2)%3]-a[(i+2)%3]) - (b[(i+2)%3]-a[(i+2)%3])*(c[(i+1)%3]-a[(i+1)%3]) for i in range(3)]
        if sum(cr[i] * n[i] for i in range(3)) < 0:
            t = (t[0], t[2], t[1])
        ci.extend(t)
cube = {"POSITION": add(cp, "f", 3, 5126, 34962, True), "NORMAL": add(cn, "f", 3, 5126, 34962)}
cube_idx = add(ci, "B", 1, 5121, 34963)

# Emissive panel: a quad in xy, not indexed.
pp = [(-0.5, 0, 0), (0.5, 0, 0), (0.5, 1, 0), (-0.5, 0, 0), (0.5, 1, 0), (-0.5, 1, 0)]
panel = {"POSITION": add(pp, "f", 3, 5126, 34962, True)}

checker = png(4, 4, [[(230, 230, 220) if (x + y) % 2 else (40, 60, 110) for x in range(4)] for y in range(4)])
# Stripes tilted left and right about v: a corrugated normal map.
t = int(127.5 + 127.5 * math.sin(0.5))
z = int(127.5 + 127.5 * math.cos(0.5))
normal = png(4, 1, [[(t, 128, z), (128, 128, 255), (255 - t, 128, z), (128, 128, 255)]])

doc = {
    "asset": {"version": "2.0", "generator": "Lucent res/scenes/make_pbr_gltf.py"},
    "extensionsUsed": ["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_emissive_strength"],
    "scene": 0,
    "scenes": [{"nodes": [0, 1, 4, 5, 6]}],
    "nodes": [
        {"name": "ground", "mesh": 0},
        {"name": "shelf", "translation": [0, 0.5, 0], "rotation": [0, math.sin(0.2), 0, math.cos(0.2)], "children": [2, 3]},
        {"name": "gold", "mesh": 1, "translation": [-0.7, 0, 0]},
        {"name": "gold2", "mesh": 1, "matrix": [0.6, 0, 0, 0, 0, 0.6, 0, 0, 0, 0, 0.6, 0, 0.7, -0.2, 0.3, 1]},
        {"name": "red", "mesh": 2, "translation": [0, 0.3, -1], "scale": [0.6, 1.6, 0.6]},
        {"name": "panel", "mesh": 3, "translation": [1.3, 0.2, -1.2], "rotation": [0, -0.3826834, 0, 0.9238795]},
        {"name": "spot", "translation": [0.3, 3, 0.5], "rotation": [-0.6755902, 0, 0, 0.7372773],
         "extensions": {"KHR_lights_punctual": {"light": 0}}},
        {"name": "camera", "translation": [0, 1.6, 3.6], "rotation": [-0.1305262, 0, 0, 0.9914449], "camera": 0},
    ],
    "cameras": [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.05}}],
    "extensions": {"KHR_lights_punctual": {"lights": [
        {"type": "spot", "color": [1, 0.95, 0.85], "intensity": 683 * 40,
         "spot": {"innerConeAngle": 0.3, "outerConeAngle": 0.6}}]}},
    "meshes": [
        {"name": "ground", "primitives": [{"attributes": ground, "indices": ground_idx, "mode": 5, "material": 0}]},
        {"name": "gold_cube", "primitives": [{"attributes": cube, "indices": cube_idx, "material": 1}]},
        {"name": "red_cube", "primitives": [{"attributes": cube, "indices": cube_idx, "material": 2}]},
        {"name": "panel", "primitives": [{"attributes": panel, "material": 3}]},
    ],
    "materials": [
        {"name": "checker", "pbrMetallicRoughness": {
            "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [3, 3], "rotation": 0.3}}},
            "metallicFactor": 0, "roughnessFactor": 0.7},
         "normalTexture": {"index": 1, "scale": 1.0}},
        {"name": "gold", "pbrMetallicRoughness": {"baseColorFactor": [1, 0.77, 0.34, 1], "metallicFactor": 1, "roughnessFactor": 0.3}},
        {"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.08, 1], "metallicFactor": 0, "roughnessFactor": 0.15}},
        {"name": "lamp", "emissiveFactor": [1, 0.8, 0.5], "doubleSided": True,
         "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 3}},
         "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.1, 0.1, 1], "metallicFactor": 0}},
    ],
    "samplers": [{"wrapS": 33648, "wrapT": 10497}, {}],
    "textures": [{"sampler": 0, "source": 0}, {"sampler": 1, "source": 1}],
    "images": [{"uri": uri(checker, "image/png")}, {"uri": uri(normal, "image/png")}],
    "accessors": accessors,
    "bufferViews": views,
    "buffers": [{"byteLength": len(blob), "uri": uri(bytes(blob), "application/octet-stream")}],
}
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "pbr-shelf.gltf")
with open(out, "w") as f:
    json.dump(doc, f, indent=1)
    f.write("\n")
print(out, len(blob), "bytes of buffer")
