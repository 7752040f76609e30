#!/usr/bin/env python3
"""Converts an OpenArena level (a Quake III BSP, version 46, from Debian's `openarena-data`,
GPL-2+) into a glTF for the corpus: the level's drawn surfaces, one mesh per texture, a
material per texture whose base colour is the texture's mean colour, and the level's `light`
entities as point lights.

    apt-get install openarena-data python3-pil
    python3 openarena_gltf.py MAP OUT_DIR     # e.g. aggressor assets/corpus/openarena

The level stays as its authors built it: Z-up, in Quake units (1 unit = 1 inch), under one
root node that turns Z-up into glTF's Y-up and scales inches to metres. What changes:
* planar and triangle-soup surfaces are kept as they are; curved (Bézier patch) surfaces are
  tessellated into 8 × 8 quads per 3 × 3 control-point piece; billboards, sky, fog, water,
  and surfaces the game does not draw are left out;
* a texture's mean colour (linear) becomes the material's base colour, clamped to 0.9; a
  texture not found in the game's archives gets 0.5 grey;
* a `light` entity's `light` value L becomes a point light of 3.8 L candela in its `_color`
  (q3map2's point scale of 7 500 with a lightmap value of 255 read as 200 lux); lights aimed
  at a target (spot lights in the game) are kept as point lights;
* the game's surface lights, sky light and ambient term are not carried over (they live in
  shader scripts, not in the level file).
Nothing else is changed. The result is byte-identical for the same package version.
"""
import io
import json
import math
import re
import struct
import sys
import zipfile
from pathlib import Path

BASE = Path("/usr/share/games/openarena/baseoa")
INCH = 0.0254
CANDELA_PER_LIGHT = 3.8
PATCH_STEPS = 8
# Surface flags (q_shared.h): SURF_SKY, SURF_NODRAW; contents: water, slime, fog.
SURF_SKY, SURF_NODRAW = 0x4, 0x80
CONTENTS_SKIP = 0x8 | 0x10 | 0x40


def archives():
    """The game's .pk3 archives, later ones overriding earlier ones (as the game loads them)."""
    return [zipfile.ZipFile(p) for p in sorted(BASE.glob("*.pk3"))]


def find(paks, name):
    """Bytes of `name` from the last archive holding it, or None."""
    for z in reversed(paks):
        try:
            return z.read(name)
        except KeyError:
            continue
    return None


def mean_colour(paks, texture):
    """Linear mean colour of a texture (its .jpg or .tga), or None when absent."""
    from PIL import Image

    for ext in (".tga", ".jpg"):
        data = find(paks, texture + ext)
        if data is None:
            continue
        img = Image.open(io.BytesIO(data)).convert("RGB").resize((32, 32), Image.BOX)
        px = list(img.getdata())

        def lin(c):
            c /= 255.0
            return c / 12.92 if c <= 0.04045 else ((c + 0.055) / 1.055) ** 2.4

        return [min(0.9, sum(lin(p[i]) for p in px) / len(px)) for i in range(3)]
    return None


def lumps(data):
    magic, version = data[:4], struct.unpack_from("<i", data, 4)[0]
    if magic != b"IBSP" or version != 46:
        sys.exit(f"not a Quake III BSP (magic {magic!r}, version {version})")
    return [struct.unpack_from("<ii", data, 8 + 8 * i) for i in range(17)]


def records(data, lump, size, fmt):
    off, length = lump
    return [struct.unpack_from(fmt, data, off + size * i) for i in range(length // size)]


def bezier(c, s, t):
    """A point of a quadratic Bézier patch piece with 3 × 3 control points `c` (rows of t)."""
    bs = [(1 - s) ** 2, 2 * s * (1 - s), s * s]
    bt = [(1 - t) ** 2, 2 * t * (1 - t), t * t]
    return [sum(bt[j] * bs[i] * c[j][i][k] for i in range(3) for j in range(3)) for k in range(len(c[0][0]))]


def patch(verts, first, width, height):
    """Positions and normals (flattened per vertex) and triangles of a tessellated patch."""
    pos, nor, tris = [], [], []
    for py in range(0, height - 1, 2):
        for px in range(0, width - 1, 2):
            c = [[verts[first + (py + j) * width + px + i] for i in range(3)] for j in range(3)]
            cp = [[v[0] for v in row] for row in c]
            cn = [[v[1] for v in row] for row in c]
            base = len(pos)
            n = PATCH_STEPS
            for j in range(n + 1):
                for i in range(n + 1):
                    pos.append(bezier(cp, i / n, j / n))
                    nv = bezier(cn, i / n, j / n)
                    ln = math.sqrt(sum(x * x for x in nv)) or 1.0
                    nor.append([x / ln for x in nv])
            for j in range(n):
                for i in range(n):
                    a = base + j * (n + 1) + i
                    # The game's patches wind clockwise seen from the front, as its polygons do.
                    tris += [(a, a + n + 1, a + 1), (a + 1, a + n + 1, a + n + 2)]
    return pos, nor, tris


def convert(name, out):
    paks = archives()
    data = find(paks, f"maps/{name}.bsp")
    if data is None:
        sys.exit(f"maps/{name}.bsp is in none of {BASE}/*.pk3 (is openarena-data installed?)")
    lp = lumps(data)
    entities = data[lp[0][0]: lp[0][0] + lp[0][1]].decode("latin1")
    textures = records(data, lp[1], 72, "<64sii")
    verts = [((v[0], v[1], v[2]), (v[7], v[8], v[9])) for v in records(data, lp[10], 44, "<3f2f2f3f4B")]
    meshverts = [m[0] for m in records(data, lp[11], 4, "<i")]
    faces = records(data, lp[13], 104, "<iiiiiiii2i2i3f3f3f3f2i")

    # Per texture: positions, normals, triangles (Quake's clockwise fronts, turned to glTF's
    # counter-clockwise).
    groups = {}
    for f in faces:
        tex, kind, first, count, mfirst, mcount = f[0], f[2], f[3], f[4], f[5], f[6]
        tname, flags, contents = textures[tex]
        if flags & (SURF_SKY | SURF_NODRAW) or contents & CONTENTS_SKIP:
            continue
        g = groups.setdefault(tex, ([], [], []))
        base = len(g[0])
        if kind in (1, 3):
            for v in verts[first: first + count]:
                g[0].append(list(v[0]))
                g[1].append(list(v[1]))
            idx = meshverts[mfirst: mfirst + mcount]
            g[2].extend((base + idx[i], base + idx[i + 2], base + idx[i + 1]) for i in range(0, len(idx) - 2, 3))
        elif kind == 2:
            p, n, t = patch(verts, first, f[24], f[25])
            g[0].extend(p)
            g[1].extend(n)
            g[2].extend((base + a, base + c, base + b) for a, b, c in t)
    groups = {k: v for k, v in groups.items() if v[2]}

    doc = {"asset": {"version": "2.0", "generator": "lightbake corpus openarena_gltf.py"},
           "extensionsUsed": ["KHR_lights_punctual"], "buffers": [], "bufferViews": [],
           "accessors": [], "materials": [], "meshes": [], "nodes": [], "scenes": [{"nodes": [0]}],
           "scene": 0}
    blob = bytearray()

    def view(raw, target):
        while len(blob) % 4:
            blob.append(0)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(raw), "target": target})
        blob.extend(raw)
        return len(doc["bufferViews"]) - 1

    def accessor(values, kind, comp, fmt, bounds):
        flat = [x for v in values for x in (v if isinstance(v, (list, tuple)) else [v])]
        raw = struct.pack(f"<{len(flat)}{fmt}", *flat)
        a = {"bufferView": view(raw, 34963 if kind == "SCALAR" else 34962), "componentType": comp,
             "count": len(values), "type": kind}
        if bounds:
            a["min"] = [min(v[i] for v in values) for i in range(3)]
            a["max"] = [max(v[i] for v in values) for i in range(3)]
        doc["accessors"].append(a)
        return len(doc["accessors"]) - 1

    root = {"name": name, "rotation": [-math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)],
            "scale": [INCH, INCH, INCH], "children": []}
    doc["nodes"].append(root)
    missing = 0
    for tex in sorted(groups):
        pos, nor, tris = groups[tex]
        tname = textures[tex][0].split(b"\0")[0].decode("latin1")
        colour = mean_colour(paks, tname)
        if colour is None:
            missing += 1
            colour = [0.5, 0.5, 0.5]
        doc["materials"].append({"name": tname, "pbrMetallicRoughness": {
            "baseColorFactor": [round(c, 4) for c in colour] + [1.0], "metallicFactor": 0.0,
            "roughnessFactor": 1.0}})
        prim = {"attributes": {"POSITION": accessor(pos, "VEC3", 5126, "f", True),
                               "NORMAL": accessor(nor, "VEC3", 5126, "f", False)},
                "indices": accessor([i for t in tris for i in t], "SCALAR", 5125, "I", False),
                "material": len(doc["materials"]) - 1}
        doc["meshes"].append({"name": tname, "primitives": [prim]})
        doc["nodes"].append({"name": tname, "mesh": len(doc["meshes"]) - 1})
        root["children"].append(len(doc["nodes"]) - 1)

    lights = []
    for block in re.findall(r"\{([^}]*)\}", entities):
        keys = dict(re.findall(r'"([^"]*)" "([^"]*)"', block))
        if keys.get("classname") != "light":
            continue
        value = float(keys.get("light", "300"))
        colour = [float(c) for c in keys.get("_color", "1 1 1").split()]
        top = max(colour) or 1.0
        lights.append({"name": f"light_{len(lights)}", "type": "point",
                       "color": [round(c / top, 4) for c in colour],
                       "intensity": round(CANDELA_PER_LIGHT * value, 3)})
        doc["nodes"].append({"name": lights[-1]["name"],
                             "translation": [float(c) for c in keys["origin"].split()],
                             "extensions": {"KHR_lights_punctual": {"light": len(lights) - 1}}})
        root["children"].append(len(doc["nodes"]) - 1)
    doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}

    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.bin").write_bytes(bytes(blob))
    doc["buffers"].append({"uri": f"{name}.bin", "byteLength": len(blob)})
    (out / f"{name}.gltf").write_text(json.dumps(doc, indent=1) + "\n")
    tri_count = sum(len(g[2]) for g in groups.values())
    print(f"{name}: {tri_count} triangles in {len(groups)} meshes, {len(lights)} point lights, "
          f"{missing} textures not found (0.5 grey)")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    convert(sys.argv[1], Path(sys.argv[2]))
