#!/usr/bin/env python3
"""Assembles the level of one of Kenney's Godot starter kits (MIT) into one glTF for the
corpus: the static pieces `scenes/main.tscn` places under the level's nodes, placed as Godot
places them (each object scene's own child pieces and node transforms included), their meshes
and materials as Kenney's .glb files hold them, and the scene's sun.

    python3 kenney_assemble.py fps PATH/TO/Starter-Kit-FPS              # writes kenney_fps/
    python3 kenney_assemble.py platformer PATH/TO/Starter-Kit-3D-Platformer

Changes to the source: the `KHR_texture_transform` entries (texCoord 0 only, the identity)
are dropped; pieces that move or vanish in play (the platformer's coins) are left out; the
sun gets an illuminance in lux and the scene a sky luminance in nits, as the corpus README
says (Godot's light energy has no physical unit). Nothing else is changed.
"""
import json
import re
import shutil
import struct
import sys
from pathlib import Path

SUN_LUX = 60000.0
# Per level: its name, the nodes of main.tscn whose children are the level's pieces, the
# object scenes left out, and the sky: Godot's ambient light colour at 5 000 nits.
LEVELS = {
    "fps": ("kenney_fps", ("Level", "Decoration"), (), [3314.0, 3471.0, 3863.0]),
    "platformer": ("kenney_platformer", ("World",), ("objects/coin.tscn",), [4050.0, 4219.0, 5000.0]),
}


def tscn(path):
    """(resources id -> path, [(name, parent, instance id, transform)]) of a .tscn file."""
    text = Path(path).read_text()
    res = dict((m[1], m[0]) for m in re.findall(r'\[ext_resource [^\]]*path="res://([^"]+)" id="([^"]+)"', text))
    nodes = []
    for block in re.split(r"\n(?=\[)", text):
        head = re.match(r"\[node ([^\]]*)\]", block)
        if not head:
            continue
        attrs = dict(re.findall(r'(\w+)="([^"]*)"', head[1]))
        inst = re.search(r'instance=ExtResource\("([^"]+)"\)', head[1])
        t = re.search(r"^transform = Transform3D\(([^)]*)\)", block, re.M)
        nodes.append((attrs.get("name"), attrs.get("parent"), inst and inst[1],
                      t and [float(v) for v in t[1].split(",")]))
    return res, nodes


def matrix(t):
    """A glTF column-major matrix from Godot's Transform3D (basis rows, then the origin)."""
    if t is None:
        return [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    r = [t[0:3], t[3:6], t[6:9]]
    return [r[0][0], r[1][0], r[2][0], 0, r[0][1], r[1][1], r[2][1], 0,
            r[0][2], r[1][2], r[2][2], 0, t[9], t[10], t[11], 1]


class Doc:
    def __init__(self):
        self.d = {"asset": {"version": "2.0", "generator": "lightbake corpus assemble.py"},
                  "buffers": [], "bufferViews": [], "accessors": [], "images": [], "samplers": [],
                  "textures": [], "materials": [], "meshes": [], "nodes": []}
        self.glbs = {}

    def load(self, root, rel, out):
        """Offsets of the glb `rel`'s arrays in the document (loaded once)."""
        if rel in self.glbs:
            return self.glbs[rel]
        b = (root / rel).read_bytes()
        n = struct.unpack("<I", b[12:16])[0]
        j = json.loads(b[20:20 + n])
        m = struct.unpack("<I", b[20 + n:24 + n])[0]
        bin_name = Path(rel).stem + ".bin"
        (out / bin_name).write_bytes(b[28 + n:28 + n + m])
        d, off = self.d, {k: len(self.d[k]) for k in self.d if isinstance(self.d[k], list)}
        d["buffers"].append({"uri": bin_name, "byteLength": j["buffers"][0]["byteLength"]})
        for v in j.get("bufferViews", []):
            d["bufferViews"].append({**v, "buffer": off["buffers"] + v["buffer"]})
        for a in j.get("accessors", []):
            d["accessors"].append({**a, "bufferView": off["bufferViews"] + a["bufferView"]})
        for im in j.get("images", []):
            d["images"].append(im)
        d["samplers"].extend(j.get("samplers", []))
        for t in j.get("textures", []):
            d["textures"].append({**t, "sampler": off["samplers"] + t["sampler"],
                                  "source": off["images"] + t["source"]})
        for mat in j.get("materials", []):
            mat = json.loads(json.dumps(mat))
            for info in [mat.get("pbrMetallicRoughness", {}).get("baseColorTexture")] + \
                    [mat.get(k) for k in ("normalTexture", "occlusionTexture", "emissiveTexture")]:
                if info:
                    info["index"] += off["textures"]
                    info.pop("extensions", None)
            d["materials"].append(mat)
        for mesh in j.get("meshes", []):
            mesh = json.loads(json.dumps(mesh))
            for p in mesh["primitives"]:
                p["attributes"] = {k: v + off["accessors"] for k, v in p["attributes"].items()}
                if "indices" in p:
                    p["indices"] += off["accessors"]
                if "material" in p:
                    p["material"] += off["materials"]
            d["meshes"].append(mesh)
        self.glbs[rel] = (j, off)
        return self.glbs[rel]

    def place(self, root, rel, out, overrides):
        """New nodes for one placement of glb `rel`'s scene; returns its root node indices."""
        j, off = self.load(root, rel, out)

        def copy(i):
            src = j["nodes"][i]
            node = {k: v for k, v in src.items() if k in ("name", "translation", "rotation", "scale", "matrix")}
            if src.get("name") in overrides:
                for k in ("translation", "rotation", "scale"):
                    node.pop(k, None)
                node["matrix"] = matrix(overrides[src["name"]])
            if "mesh" in src:
                node["mesh"] = off["meshes"] + src["mesh"]
            kids = [copy(c) for c in src.get("children", [])]
            if kids:
                node["children"] = kids
            self.d["nodes"].append(node)
            return len(self.d["nodes"]) - 1

        return [copy(i) for i in j["scenes"][j.get("scene", 0)]["nodes"]]

    def node(self, **kw):
        self.d["nodes"].append(kw)
        return len(self.d["nodes"]) - 1


def main():
    name, parents, skip, sky = LEVELS[sys.argv[1]]
    root = Path(sys.argv[2])
    out = Path(sys.argv[3]) if len(sys.argv) > 3 else Path(__file__).parent / name
    (out / "Textures").mkdir(parents=True, exist_ok=True)
    shutil.copyfile(root / "models/Textures/colormap.png", out / "Textures/colormap.png")
    doc = Doc()
    res, nodes = tscn(root / "scenes/main.tscn")
    scene_nodes = []

    def object_scene(rel, name, t):
        """A placement of `rel`: a glb, or an object scene (its glb, node overrides and pieces)."""
        if rel.endswith(".glb"):
            return doc.node(name=name, matrix=matrix(t), children=doc.place(root, rel, out, {}))
        ores, onodes = tscn(root / rel)
        top = onodes[0][2]
        overrides = {n: tr for (n, parent, inst, tr) in onodes[1:] if parent == "." and inst is None and tr}
        kids = doc.place(root, ores[top], out, overrides) if top and ores[top].endswith(".glb") else []
        for (n, parent, inst, tr) in onodes[1:]:
            if parent == "." and inst is not None and ores[inst].endswith(".glb"):
                kids.append(doc.node(name=n, matrix=matrix(tr), children=doc.place(root, ores[inst], out, {})))
        return doc.node(name=name, matrix=matrix(t), children=kids)

    for (node, parent, inst, t) in nodes:
        if parent in parents and inst is not None and res[inst] not in skip:
            scene_nodes.append(object_scene(res[inst], node, t))
        if node == "Sun":
            doc.d["extensionsUsed"] = ["KHR_lights_punctual"]
            doc.d["extensions"] = {"KHR_lights_punctual": {"lights": [
                {"name": "sun", "type": "directional", "color": [1.0, 0.96, 0.9], "intensity": SUN_LUX}]}}
            scene_nodes.append(doc.node(name="sun", matrix=matrix(t), extensions={"KHR_lights_punctual": {"light": 0}}))
    doc.d["scenes"] = [{"name": name, "nodes": scene_nodes, "extras": {"lightbake": {"sky": sky}}}]
    doc.d["scene"] = 0
    (out / (name + ".gltf")).write_text(json.dumps(doc.d, indent=1) + "\n")


if __name__ == "__main__":
    main()
