#!/usr/bin/env python3
"""Makes two small corpus scenes from Debian's `assimp-testmodels` (assimp's own test files,
BSD-3-clause), converted by `assimp export` (Debian `assimp-utils`) as a user's pipeline would:

    python3 assimp_scenes.py teapots OUT_DIR          # writes OUT_DIR/teapots.gltf, .bin, Textures/
    python3 assimp_scenes.py mirrored_cubes OUT_DIR   # writes OUT_DIR/mirrored_cubes.gltf, .bin

* `teapots`: `Collada/teapots.DAE`, three teapots exported from 3ds Max, authored Z-up in
  centimetres (`<unit meter="0.01">`). assimp keeps the vertices in centimetres and puts the
  unit and the axis change in the root node's matrix (scale 0.01, Z-up turned Y-up).
* `mirrored_cubes`: `FBX/cubes_with_mirroring_and_pivot.fbx`, four cubes, two of them under a
  node mirrored in y (scale −0.1), with FBX pivots that assimp writes as helper nodes.

Changes to the converted files, all listed here: a ground square is added under the models
(4 m for the teapots, 1 m for the cubes; albedo 0.5; in metres, on the models' lowest point,
so the teapots stand on it); a sun (80 000 lx, 40° up) and a sky (about 2 000 nits) are added
as `KHR_lights_punctual` and lightbake's scene extras; the teapots' materials are made opaque
(assimp reads the Collada file's transparency as alpha 0 with `BLEND`, where the file's
reference image shows opaque teapots); the teapot texture, which the Collada file names by a
relative Windows path into the package's LWO folder, is copied to `Textures/` and named there.
Nothing else is changed: meshes, units, node matrices, mirroring and materials are the
converter's.
"""
import json
import math
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

MODELS = Path("/usr/share/assimp/models")
SCENES = {
    # name: (source file, ground square's side in metres, make materials opaque)
    "teapots": (MODELS / "Collada/teapots.DAE", 4.0, True),
    "mirrored_cubes": (MODELS / "FBX/cubes_with_mirroring_and_pivot.fbx", 1.0, False),
}
SUN_LUX = 80000.0
SKY_NITS = [1800.0, 2250.0, 3000.0]


def matmul(a, b):
    """4×4 product of two column-major glTF matrices."""
    return [sum(a[k * 4 + r] * b[c * 4 + k] for k in range(4)) for c in range(4) for r in range(4)]


def local(node):
    """A node's column-major local matrix (assimp writes `matrix` or nothing)."""
    if "matrix" in node:
        return node["matrix"]
    assert not any(k in node for k in ("translation", "rotation", "scale")), node
    return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def world_points(doc, blob):
    """Every mesh vertex in world space, through the scene's node hierarchy."""
    points = []

    def visit(i, parent):
        m = matmul(parent, local(doc["nodes"][i]))
        node = doc["nodes"][i]
        if "mesh" in node:
            for prim in doc["meshes"][node["mesh"]]["primitives"]:
                acc = doc["accessors"][prim["attributes"]["POSITION"]]
                view = doc["bufferViews"][acc["bufferView"]]
                start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
                stride = view.get("byteStride", 12)
                for v in range(acc["count"]):
                    x, y, z = struct.unpack_from("<3f", blob, start + v * stride)
                    points.append([m[0] * x + m[4] * y + m[8] * z + m[12],
                                   m[1] * x + m[5] * y + m[9] * z + m[13],
                                   m[2] * x + m[6] * y + m[10] * z + m[14]])
        for c in node.get("children", []):
            visit(c, m)

    for root in doc["scenes"][doc.get("scene", 0)]["nodes"]:
        visit(root, [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1])
    return points


def add_view(doc, blob, data, target):
    """Appends `data` (4-byte aligned) to the buffer as a new buffer view; its index."""
    blob.extend(b"\0" * (-len(blob) % 4))
    doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data),
                               "target": target})
    blob.extend(data)
    return len(doc["bufferViews"]) - 1


def add_ground(doc, blob, side, points):
    """A square of `side` metres at the models' lowest y, centred under them, facing up."""
    lo = [min(p[k] for p in points) for k in range(3)]
    hi = [max(p[k] for p in points) for k in range(3)]
    cx, cz, y, h = (lo[0] + hi[0]) / 2, (lo[2] + hi[2]) / 2, lo[1], side / 2
    corners = [(cx - h, y, cz - h), (cx + h, y, cz - h), (cx + h, y, cz + h), (cx - h, y, cz + h)]
    pos = add_view(doc, blob, b"".join(struct.pack("<3f", *c) for c in corners), 34962)
    nrm = add_view(doc, blob, struct.pack("<3f", 0, 1, 0) * 4, 34962)
    idx = add_view(doc, blob, struct.pack("<6H", 0, 2, 1, 0, 3, 2), 34963)
    acc = doc["accessors"]
    acc.append({"bufferView": pos, "componentType": 5126, "count": 4, "type": "VEC3",
                "min": [cx - h, y, cz - h], "max": [cx + h, y, cz + h]})
    acc.append({"bufferView": nrm, "componentType": 5126, "count": 4, "type": "VEC3"})
    acc.append({"bufferView": idx, "componentType": 5123, "count": 6, "type": "SCALAR"})
    doc["materials"].append({"name": "ground", "pbrMetallicRoughness": {
        "baseColorFactor": [0.5, 0.5, 0.5, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}})
    doc["meshes"].append({"name": "ground", "primitives": [{
        "attributes": {"POSITION": len(acc) - 3, "NORMAL": len(acc) - 2},
        "indices": len(acc) - 1, "material": len(doc["materials"]) - 1}]})
    doc["nodes"].append({"name": "ground", "mesh": len(doc["meshes"]) - 1})
    doc["scenes"][doc.get("scene", 0)]["nodes"].append(len(doc["nodes"]) - 1)
    return lo, hi


def add_lights(doc):
    """The sun, 40° up from azimuth 215°, on a node whose −z is its direction, and the sky."""
    elevation, azimuth = math.radians(40.0), math.radians(215.0)
    to_sun = (math.cos(elevation) * math.sin(azimuth), math.sin(elevation),
              math.cos(elevation) * math.cos(azimuth))
    # The rotation taking −z to −to_sun: axis (−z) × (−to_sun), angle between them.
    fx, fy, fz = 0.0, 0.0, -1.0
    tx, ty, tz = -to_sun[0], -to_sun[1], -to_sun[2]
    ax = (fy * tz - fz * ty, fz * tx - fx * tz, fx * ty - fy * tx)
    norm = math.sqrt(sum(a * a for a in ax))
    angle = math.acos(max(-1.0, min(1.0, fx * tx + fy * ty + fz * tz)))
    s = math.sin(angle / 2) / norm
    doc.setdefault("extensionsUsed", []).append("KHR_lights_punctual")
    doc.setdefault("extensions", {})["KHR_lights_punctual"] = {"lights": [{
        "name": "sun", "type": "directional", "color": [1.0, 0.95, 0.88], "intensity": SUN_LUX,
        "extras": {"lightbake": {"angular_radius": 0.00465}}}]}
    doc["nodes"].append({"name": "sun", "rotation": [ax[0] * s, ax[1] * s, ax[2] * s,
                                                     math.cos(angle / 2)],
                         "extensions": {"KHR_lights_punctual": {"light": 0}}})
    scene = doc["scenes"][doc.get("scene", 0)]
    scene["nodes"].append(len(doc["nodes"]) - 1)
    scene.setdefault("extras", {})["lightbake"] = {"sky": SKY_NITS}


def main(name, out):
    source, side, opaque = SCENES[name]
    with tempfile.TemporaryDirectory() as tmp:
        gltf = Path(tmp) / f"{name}.gltf"
        subprocess.run(["assimp", "export", str(source), str(gltf), "-fgltf2"], check=True,
                       stdout=subprocess.DEVNULL)
        doc = json.loads(gltf.read_text())
        blob = bytearray((Path(tmp) / doc["buffers"][0]["uri"]).read_bytes())
    assert len(doc["buffers"]) == 1, "assimp wrote one buffer"
    points = world_points(doc, blob)
    lo, hi = add_ground(doc, blob, side, points)
    add_lights(doc)
    if opaque:
        for m in doc["materials"]:
            m.pop("alphaMode", None)
            pbr = m.get("pbrMetallicRoughness", {})
            if "baseColorFactor" in pbr:
                pbr["baseColorFactor"][3] = 1.0
    out.mkdir(parents=True, exist_ok=True)
    for image in doc.get("images", []):
        src = (source.parent / image["uri"].replace("\\", "/")).resolve()
        (out / "Textures").mkdir(exist_ok=True)
        shutil.copyfile(src, out / "Textures" / src.name)
        image["uri"] = f"Textures/{src.name}"
    doc["buffers"][0] = {"byteLength": len(blob), "uri": f"{name}.bin"}
    doc["asset"]["generator"] += "; lightbake corpus assimp_scenes.py"
    (out / f"{name}.bin").write_bytes(bytes(blob))
    (out / f"{name}.gltf").write_text(json.dumps(doc, indent=1, sort_keys=True) + "\n")
    print(f"wrote {out / name}.gltf: models span {[round(v, 3) for v in lo]} .. "
          f"{[round(v, 3) for v in hi]} m")


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in SCENES:
        sys.exit(f"usage: {sys.argv[0]} {{{','.join(SCENES)}}} OUT_DIR")
    main(sys.argv[1], Path(sys.argv[2]))
