//! A small glTF to start every case from (a 2 m floor and a 0.5 m box on it, under a point
//! light), with helpers to add buffers, views, accessors and images, and PNG bytes.

use serde_json::{Value, json};

/// A `.gltf` document and its buffer 0.
#[derive(Clone)]
pub struct Doc {
    /// The JSON document.
    pub json: Value,
    /// Buffer 0's bytes (written as `scene.bin`, or embedded when the case says so).
    pub bin: Vec<u8>,
}

fn f32s(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

/// Positions, normals and u16 indices of an axis-aligned box's outward faces.
fn cuboid(lo: [f32; 3], hi: [f32; 3]) -> (Vec<f32>, Vec<f32>, Vec<u16>) {
    let (mut p, mut n, mut idx) = (Vec::new(), Vec::new(), Vec::new());
    let faces: [([f32; 3], [[f32; 3]; 4]); 6] = [
        (
            [0.0, 1.0, 0.0],
            [
                [lo[0], hi[1], lo[2]],
                [lo[0], hi[1], hi[2]],
                [hi[0], hi[1], hi[2]],
                [hi[0], hi[1], lo[2]],
            ],
        ),
        (
            [0.0, -1.0, 0.0],
            [
                [lo[0], lo[1], lo[2]],
                [hi[0], lo[1], lo[2]],
                [hi[0], lo[1], hi[2]],
                [lo[0], lo[1], hi[2]],
            ],
        ),
        (
            [1.0, 0.0, 0.0],
            [
                [hi[0], lo[1], lo[2]],
                [hi[0], hi[1], lo[2]],
                [hi[0], hi[1], hi[2]],
                [hi[0], lo[1], hi[2]],
            ],
        ),
        (
            [-1.0, 0.0, 0.0],
            [
                [lo[0], lo[1], lo[2]],
                [lo[0], lo[1], hi[2]],
                [lo[0], hi[1], hi[2]],
                [lo[0], hi[1], lo[2]],
            ],
        ),
        (
            [0.0, 0.0, 1.0],
            [
                [lo[0], lo[1], hi[2]],
                [hi[0], lo[1], hi[2]],
                [hi[0], hi[1], hi[2]],
                [lo[0], hi[1], hi[2]],
            ],
        ),
        (
            [0.0, 0.0, -1.0],
            [
                [lo[0], lo[1], lo[2]],
                [lo[0], hi[1], lo[2]],
                [hi[0], hi[1], lo[2]],
                [hi[0], lo[1], lo[2]],
            ],
        ),
    ];
    for (normal, corners) in faces {
        let base = (p.len() / 3) as u16;
        for c in corners {
            p.extend_from_slice(&c);
            n.extend_from_slice(&normal);
        }
        idx.extend_from_slice(&[base, base + 1, base + 2, base, base + 2, base + 3]);
    }
    (p, n, idx)
}

impl Doc {
    /// The base scene: floor (mesh 0) and box (mesh 1), one point light, one material.
    pub fn base() -> Self {
        let mut doc = Doc {
            json: json!({
                "asset": { "version": "2.0" },
                "scene": 0,
                "scenes": [{ "nodes": [0, 1, 2] }],
                "nodes": [
                    { "name": "floor", "mesh": 0 },
                    { "name": "box", "mesh": 1 },
                    { "name": "lamp", "translation": [0.3, 1.2, 0.2],
                      "extensions": { "KHR_lights_punctual": { "light": 0 } } }
                ],
                "meshes": [],
                "materials": [{ "name": "grey", "pbrMetallicRoughness": {
                    "baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0 } }],
                "buffers": [{ "byteLength": 0, "uri": "scene.bin" }],
                "bufferViews": [],
                "accessors": [],
                "extensionsUsed": ["KHR_lights_punctual"],
                "extensions": { "KHR_lights_punctual": { "lights": [
                    { "name": "lamp", "type": "point", "intensity": 20.0, "color": [1, 1, 1] }
                ] } }
            }),
            bin: Vec::new(),
        };
        let floor_p = [
            -1.0, 0.0, -1.0, -1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 0.0, -1.0,
        ];
        let floor_n = [0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0];
        doc.add_mesh("floor", &floor_p, &floor_n, &[0, 1, 2, 0, 2, 3]);
        let (p, n, i) = cuboid([-0.25, 0.0, -0.25], [0.25, 0.5, 0.25]);
        doc.add_mesh("box", &p, &n, &i);
        doc
    }

    /// Appends bytes to buffer 0 (4-byte aligned) as a new view; returns its index.
    pub fn add_view(&mut self, bytes: &[u8]) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.json["buffers"][0]["byteLength"] = json!(self.bin.len());
        let views = self.json["bufferViews"].as_array_mut().unwrap();
        views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": bytes.len() }));
        views.len() - 1
    }

    /// Adds an accessor; returns its index.
    pub fn add_accessor(&mut self, accessor: Value) -> usize {
        let list = self.json["accessors"].as_array_mut().unwrap();
        list.push(accessor);
        list.len() - 1
    }

    /// Adds a mesh of one triangle primitive with the material 0; returns its index.
    pub fn add_mesh(&mut self, name: &str, p: &[f32], n: &[f32], idx: &[u16]) -> usize {
        let count = p.len() / 3;
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for v in p.chunks(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        let pv = self.add_view(&f32s(p));
        let nv = self.add_view(&f32s(n));
        let iv = self.add_view(&idx.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<_>>());
        let pa = self.add_accessor(json!({ "bufferView": pv, "componentType": 5126,
            "count": count, "type": "VEC3", "min": lo, "max": hi }));
        let na = self.add_accessor(
            json!({ "bufferView": nv, "componentType": 5126, "count": count, "type": "VEC3" }),
        );
        let ia = self.add_accessor(json!({ "bufferView": iv, "componentType": 5123,
            "count": idx.len(), "type": "SCALAR" }));
        let meshes = self.json["meshes"].as_array_mut().unwrap();
        meshes.push(json!({ "name": name, "primitives": [{
            "attributes": { "POSITION": pa, "NORMAL": na }, "indices": ia, "material": 0 }] }));
        meshes.len() - 1
    }

    /// Adds a mesh of u32 indices (for meshes past 65 536 vertices); returns its index.
    pub fn add_mesh_u32(&mut self, name: &str, p: &[f32], n: &[f32], idx: &[u32]) -> usize {
        let count = p.len() / 3;
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for v in p.chunks(3) {
            for k in 0..3 {
                lo[k] = lo[k].min(v[k]);
                hi[k] = hi[k].max(v[k]);
            }
        }
        let pv = self.add_view(&f32s(p));
        let nv = self.add_view(&f32s(n));
        let iv = self.add_view(&idx.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<_>>());
        let pa = self.add_accessor(json!({ "bufferView": pv, "componentType": 5126,
            "count": count, "type": "VEC3", "min": lo, "max": hi }));
        let na = self.add_accessor(
            json!({ "bufferView": nv, "componentType": 5126, "count": count, "type": "VEC3" }),
        );
        let ia = self.add_accessor(json!({ "bufferView": iv, "componentType": 5125,
            "count": idx.len(), "type": "SCALAR" }));
        let meshes = self.json["meshes"].as_array_mut().unwrap();
        meshes.push(json!({ "name": name, "primitives": [{
            "attributes": { "POSITION": pa, "NORMAL": na }, "indices": ia, "material": 0 }] }));
        meshes.len() - 1
    }

    /// A scene of one flat floor of `nx × nz` cells of `cell` metres (two triangles each,
    /// shared vertices), optionally gently curved (a bump of `bump` metres), lit by a sun.
    pub fn grid(nx: usize, nz: usize, cell: f32, bump: f32) -> Self {
        let mut doc = Self::empty();
        let (w, d) = (nx as f32 * cell, nz as f32 * cell);
        let (mut p, mut n) = (Vec::new(), Vec::new());
        for j in 0..=nz {
            for i in 0..=nx {
                let (x, z) = (i as f32 * cell - 0.5 * w, j as f32 * cell - 0.5 * d);
                let y = bump
                    * (std::f32::consts::PI * x / w).cos()
                    * (std::f32::consts::PI * z / d).cos();
                p.extend_from_slice(&[x, y, z]);
                n.extend_from_slice(&[0.0, 1.0, 0.0]);
            }
        }
        let mut idx = Vec::new();
        let row = (nx + 1) as u32;
        for j in 0..nz as u32 {
            for i in 0..nx as u32 {
                let a = j * row + i;
                idx.extend_from_slice(&[a, a + row, a + row + 1, a, a + row + 1, a + 1]);
            }
        }
        doc.add_mesh_u32("floor", &p, &n, &idx);
        doc.json["nodes"] = json!([{ "name": "floor", "mesh": 0 }, { "name": "sun",
            "rotation": [-0.5, 0.0, 0.0, 0.866],
            "extensions": { "KHR_lights_punctual": { "light": 0 } } }]);
        doc.json["scenes"][0]["nodes"] = json!([0, 1]);
        doc.json["extensions"]["KHR_lights_punctual"]["lights"] =
            json!([{ "name": "sun", "type": "directional", "intensity": 3.0 }]);
        doc
    }

    /// A scene of `n` separate small triangles scattered over a 100 m square (a triangle soup),
    /// lit by a sun.
    pub fn soup(n: usize) -> Self {
        let mut doc = Self::grid(1, 1, 1.0, 0.0);
        let (mut p, mut nn, mut idx) = (Vec::new(), Vec::new(), Vec::new());
        let mut state = 0x9e37_79b9_u32;
        let mut rnd = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as f32 / u32::MAX as f32
        };
        for t in 0..n as u32 {
            let (x, y, z) = (rnd() * 100.0 - 50.0, rnd() * 10.0, rnd() * 100.0 - 50.0);
            let s = 0.05 + 0.1 * rnd();
            p.extend_from_slice(&[x, y, z, x + s, y, z, x, y, z + s]);
            nn.extend_from_slice(&[0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0]);
            idx.extend_from_slice(&[3 * t, 3 * t + 2, 3 * t + 1]);
        }
        let m = doc.add_mesh_u32("soup", &p, &nn, &idx);
        doc.json["nodes"]
            .as_array_mut()
            .unwrap()
            .push(json!({ "name": "soup", "mesh": m }));
        doc.json["scenes"][0]["nodes"] = json!([0, 1, 2]);
        doc
    }

    /// The base scene's document with no meshes, views or accessors.
    fn empty() -> Self {
        let mut doc = Self::base();
        doc.bin.clear();
        doc.json["meshes"] = json!([]);
        doc.json["bufferViews"] = json!([]);
        doc.json["accessors"] = json!([]);
        doc.json["buffers"][0]["byteLength"] = json!(0);
        doc
    }

    /// Gives material 0 a base colour texture of image `image` (texture and sampler added);
    /// returns the texture index.
    pub fn texture_image(&mut self, image: Value) -> usize {
        if !self.json["images"].is_array() {
            self.json["images"] = json!([]);
            self.json["textures"] = json!([]);
        }
        let images = self.json["images"].as_array_mut().unwrap();
        images.push(image);
        let source = images.len() - 1;
        let textures = self.json["textures"].as_array_mut().unwrap();
        textures.push(json!({ "source": source }));
        let t = textures.len() - 1;
        self.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
            json!({ "index": t });
        t
    }

    /// The files of a `.gltf` case: `scene.gltf` and `scene.bin`.
    pub fn files(&self) -> Vec<(String, Vec<u8>)> {
        vec![
            (
                "scene.gltf".into(),
                serde_json::to_vec_pretty(&self.json).unwrap(),
            ),
            ("scene.bin".into(), self.bin.clone()),
        ]
    }

    /// The files with buffer 0 named `uri` instead of `scene.bin` (and written there unless
    /// `write` is false).
    pub fn files_with_buffer_uri(&self, uri: &str, write: Option<&str>) -> Vec<(String, Vec<u8>)> {
        let mut json = self.json.clone();
        json["buffers"][0]["uri"] = json!(uri);
        let mut files = vec![(
            "scene.gltf".into(),
            serde_json::to_vec_pretty(&json).unwrap(),
        )];
        if let Some(path) = write {
            files.push((path.to_string(), self.bin.clone()));
        }
        files
    }

    /// A binary glTF of the document (buffer 0 as its BIN chunk).
    pub fn glb(&self) -> Vec<u8> {
        let mut json = self.json.clone();
        json["buffers"][0] = json!({ "byteLength": self.bin.len() });
        let mut text = serde_json::to_vec(&json).unwrap();
        while !text.len().is_multiple_of(4) {
            text.push(b' ');
        }
        let mut bin = self.bin.clone();
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        let total = 12 + 8 + text.len() + 8 + bin.len();
        let mut out = Vec::new();
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(text.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&text);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }
}

/// A `w × h` PNG of one colour.
pub fn png(w: u32, h: u32, rgba: [u8; 4]) -> Vec<u8> {
    let img = image::RgbaImage::from_pixel(w, h, image::Rgba(rgba));
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut c = 0xffff_ffffu32;
    for &b in bytes {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xedb8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A PNG whose header claims `w × h` RGBA pixels, with a tiny (truncated) image stream.
pub fn png_claiming(w: u32, h: u32) -> Vec<u8> {
    let mut out = vec![0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];
    let mut chunk = |kind: &[u8], data: &[u8]| {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 6, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    chunk(b"IEND", &[]);
    out
}
