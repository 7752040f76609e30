//! Hostile glTF files: reads outside the scene's folder, counts that nothing backs, images
//! too large to decode, node graphs that explode, malformed containers.

use serde_json::json;

use super::gltf::{Doc, png, png_claiming};
use super::{Case, Expect};

fn gltf_only(doc: &Doc) -> Vec<(String, Vec<u8>)> {
    vec![(
        "scene.gltf".into(),
        serde_json::to_vec_pretty(&doc.json).unwrap(),
    )]
}

/// The base scene with an edited document.
fn edited(name: &str, expect: Expect, edit: impl FnOnce(&mut Doc)) -> Case {
    let mut doc = Doc::base();
    edit(&mut doc);
    Case::bake(name, doc.files(), expect)
}

/// A textured base scene whose image has `uri` (the files of the scene plus `extra`).
fn textured(name: &str, uri: &str, extra: Vec<(String, Vec<u8>)>, expect: Expect) -> Case {
    let mut doc = Doc::base();
    doc.texture_image(json!({ "uri": uri }));
    let mut files = doc.files();
    files.extend(extra);
    Case::bake(name, files, expect)
}

/// Buffer and image URIs that leave the scene's folder, and what stays inside it.
pub fn file_access() -> Vec<Case> {
    let doc = Doc::base();
    let mut cases = vec![
        Case::bake(
            "buffer ../ escape",
            doc.files_with_buffer_uri("../secret/passwd", None),
            Expect::Refuse("../secret/passwd"),
        ),
        Case::bake(
            "buffer deep ../ escape",
            doc.files_with_buffer_uri("../../../../../../../../etc/passwd", None),
            Expect::Refuse("etc/passwd"),
        ),
        Case::bake(
            "buffer absolute path",
            doc.files_with_buffer_uri("{secret}/passwd", None),
            Expect::Refuse("passwd"),
        ),
        Case::bake(
            "buffer file: URI",
            doc.files_with_buffer_uri("file://{secret}/passwd", None),
            Expect::Refuse("file:"),
        ),
        Case::bake(
            "buffer percent-encoded ../",
            doc.files_with_buffer_uri("%2e%2e/secret/passwd", None),
            Expect::Refuse("%2e%2e"),
        ),
        Case::bake(
            "buffer percent-encoded slash",
            doc.files_with_buffer_uri("..%2Fsecret%2Fpasswd", None),
            Expect::Refuse("..%2F"),
        ),
        Case::bake(
            "buffer http: URI",
            doc.files_with_buffer_uri("http://example.invalid/scene.bin", None),
            Expect::Refuse("http:"),
        ),
        Case::bake(
            "buffer non-UTF-8 escape",
            doc.files_with_buffer_uri("a%FF.bin", None),
            Expect::Refuse("a%FF.bin"),
        ),
        Case::bake(
            "buffer NUL escape",
            doc.files_with_buffer_uri("scene.bin%00.png", None),
            Expect::Refuse("%00"),
        ),
        Case::bake(
            "buffer is a directory",
            {
                let mut f = doc.files_with_buffer_uri("sub", None);
                f.push(("sub/x".into(), vec![1]));
                f
            },
            Expect::Refuse("sub"),
        ),
        Case::bake(
            "buffer with spaces, percent-encoded",
            doc.files_with_buffer_uri("my%20scene.bin", Some("my scene.bin")),
            Expect::Bake,
        ),
        Case::bake(
            "buffer in a subfolder",
            doc.files_with_buffer_uri("data/scene.bin", Some("data/scene.bin")),
            Expect::Bake,
        ),
        Case::bake(
            "buffer ./ and inner .. staying inside",
            doc.files_with_buffer_uri("./data/../scene.bin", Some("scene.bin")),
            Expect::Bake,
        ),
    ];
    // A symbolic link in the scene's folder pointing outside it.
    let mut link = Case::bake(
        "buffer through a symlink out",
        doc.files_with_buffer_uri("link.bin", None),
        Expect::Refuse("link.bin"),
    );
    link.links
        .push(("link.bin".into(), "{secret}/passwd".into()));
    cases.push(link);
    let mut dir_link = Case::bake(
        "buffer through a linked folder",
        doc.files_with_buffer_uri("shared/passwd", None),
        Expect::Refuse("shared/passwd"),
    );
    dir_link.links.push(("shared".into(), "{secret}".into()));
    cases.push(dir_link);
    let mut inside_link = Case::bake(
        "buffer through a symlink inside",
        doc.files_with_buffer_uri("alias.bin", Some("real.bin")),
        Expect::Bake,
    );
    inside_link
        .links
        .push(("alias.bin".into(), "real.bin".into()));
    cases.push(inside_link);
    let mut dev = Case::bake(
        "buffer through a link to /dev/zero",
        doc.files_with_buffer_uri("zero.bin", None),
        Expect::Refuse("zero.bin"),
    );
    dev.links.push(("zero.bin".into(), "/dev/zero".into()));
    cases.push(dev);
    let mut fifo = Case::bake(
        "buffer is a FIFO",
        doc.files_with_buffer_uri("pipe.bin", None),
        Expect::Refuse("pipe.bin"),
    );
    fifo.fifos.push("pipe.bin".into());
    fifo.timeout = 30.0;
    cases.push(fifo);
    // An extra buffer no accessor uses, pointing outside: never read, never written.
    cases.push(edited(
        "unused buffer pointing outside",
        Expect::Either,
        |d| {
            d.json["buffers"]
                .as_array_mut()
                .unwrap()
                .push(json!({ "byteLength": 20, "uri": "../secret/passwd" }));
        },
    ));
    cases.push(edited("unused buffer that is missing", Expect::Bake, |d| {
        d.json["buffers"]
            .as_array_mut()
            .unwrap()
            .push(json!({ "byteLength": 20, "uri": "nothing-here.bin" }));
    }));
    cases.push(edited("buffer data: URI", Expect::Bake, |d| {
        let encoded = base64(&d.bin);
        d.json["buffers"][0]["uri"] =
            json!(format!("data:application/octet-stream;base64,{encoded}"));
    }));
    cases.push(edited(
        "buffer data: URI not base64",
        Expect::Refuse("buffer 0"),
        |d| {
            d.json["buffers"][0]["uri"] = json!("data:application/octet-stream;base64,@@@@");
        },
    ));
    // Images.
    let tex = |name: &str| (name.to_string(), png(4, 4, [10, 200, 10, 255]));
    cases.extend([
        textured(
            "image ../ escape",
            "../secret/secret.png",
            vec![],
            Expect::Refuse("secret.png"),
        ),
        textured(
            "image absolute path",
            "{secret}/secret.png",
            vec![],
            Expect::Refuse("secret.png"),
        ),
        textured(
            "image file: URI",
            "file://{secret}/secret.png",
            vec![],
            Expect::Refuse("file:"),
        ),
        textured(
            "image percent-encoded ../",
            "%2E%2E/secret/secret.png",
            vec![],
            Expect::Refuse("%2E%2E"),
        ),
        textured(
            "image non-UTF-8 escape",
            "%FF.png",
            vec![],
            Expect::Refuse("%FF.png"),
        ),
        textured(
            "image in a subfolder",
            "tex/green.png",
            vec![tex("tex/green.png")],
            Expect::Bake,
        ),
        textured("image missing", "nothing.png", vec![], Expect::Either),
        textured("image is not an image", "scene.bin", vec![], Expect::Either),
        textured(
            "image header claims 100000²",
            "huge.png",
            vec![("huge.png".into(), png_claiming(100_000, 100_000))],
            Expect::Either,
        ),
        textured(
            "image header claims 2³¹ wide",
            "wide.png",
            vec![("wide.png".into(), png_claiming(0x7fff_ffff, 1))],
            Expect::Either,
        ),
    ]);
    let mut image_link = textured(
        "image through a symlink out",
        "link.png",
        vec![],
        Expect::Refuse("link.png"),
    );
    image_link
        .links
        .push(("link.png".into(), "{secret}/secret.png".into()));
    cases.push(image_link);
    // A shared texture folder named with --allow-read is readable (and copied out).
    cases.push(
        textured(
            "image in an --allow-read folder",
            "../shared/tex.png",
            vec![tex("../shared/tex.png")],
            Expect::Bake,
        )
        .with_args(&["--allow-read", "{root}/shared"]),
    );
    cases.push(textured(
        "image in a shared folder not allowed",
        "../shared/tex.png",
        vec![tex("../shared/tex.png")],
        Expect::Refuse("tex.png"),
    ));
    // Embedded images.
    cases.push(edited(
        "image bufferView beyond its buffer",
        Expect::Refuse("image 0"),
        |d| {
            let v = d.add_view(&png(2, 2, [1, 2, 3, 255]));
            d.json["bufferViews"][v]["byteOffset"] = json!(1_000_000);
            d.texture_image(json!({ "bufferView": v, "mimeType": "image/png" }));
        },
    ));
    cases.push(edited("image in a bufferView", Expect::Bake, |d| {
        let v = d.add_view(&png(2, 2, [1, 2, 3, 255]));
        d.texture_image(json!({ "bufferView": v, "mimeType": "image/png" }));
    }));
    cases.push(edited("image data: URI", Expect::Bake, |d| {
        let uri = format!(
            "data:image/png;base64,{}",
            base64(&png(2, 2, [9, 9, 200, 255]))
        );
        d.texture_image(json!({ "uri": uri }));
    }));
    // One image behind twelve textures: decoded once.
    cases.push({
        let mut doc = Doc::base();
        doc.texture_image(json!({ "uri": "big.png" }));
        for _ in 0..11 {
            doc.json["textures"]
                .as_array_mut()
                .unwrap()
                .push(json!({ "source": 0 }));
        }
        for k in 1..12 {
            let mut m = doc.json["materials"][0].clone();
            m["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": k });
            m["emissiveTexture"] = json!({ "index": k });
            doc.json["materials"].as_array_mut().unwrap().push(m);
        }
        let mut files = doc.files();
        files.push(("big.png".into(), png(1024, 1024, [120, 120, 120, 255])));
        Case::bake("one image behind twelve textures", files, Expect::Bake)
    });
    cases
}

/// Counts that no data backs, and arithmetic that overflows.
pub fn counts() -> Vec<Case> {
    vec![
        edited(
            "POSITION count 2³¹ over 48 bytes",
            Expect::Refuse("POSITION"),
            |d| {
                d.json["accessors"][0]["count"] = json!(1u64 << 31);
            },
        ),
        edited("index count 2⁶¹", Expect::Refuse("indices"), |d| {
            d.json["accessors"][2]["count"] = json!(1u64 << 61);
        }),
        edited(
            "index count 2⁶¹ without a view",
            Expect::Refuse("accessors[2]"),
            |d| {
                d.json["accessors"][2]["count"] = json!(1u64 << 61);
                d.json["accessors"][2]
                    .as_object_mut()
                    .unwrap()
                    .remove("bufferView");
            },
        ),
        edited(
            "POSITION of 10⁹ zeros (no view)",
            Expect::Refuse("accessors[0]"),
            |d| {
                d.json["accessors"][0]["count"] = json!(1_000_000_000u64);
                d.json["accessors"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("bufferView");
            },
        ),
        edited("sparse count 2⁶²", Expect::Refuse("sparse"), |d| {
            d.json["accessors"][0]["sparse"] = json!({ "count": 1u64 << 62,
                "indices": { "bufferView": 2, "componentType": 5123 },
                "values": { "bufferView": 0 } });
        }),
        edited("sparse count 2³² − 1", Expect::Refuse("sparse"), |d| {
            d.json["accessors"][0]["sparse"] = json!({ "count": u32::MAX,
                "indices": { "bufferView": 2, "componentType": 5125 },
                "values": { "bufferView": 0 } });
        }),
        edited("byteOffset near 2⁶⁴", Expect::Refuse("POSITION"), |d| {
            d.json["accessors"][0]["byteOffset"] = json!(u64::MAX - 8);
        }),
        edited(
            "byteStride 252 past the view",
            Expect::Refuse("POSITION"),
            |d| {
                d.json["bufferViews"][0]["byteStride"] = json!(252);
            },
        ),
        edited(
            "bufferView beyond its buffer",
            Expect::Refuse("bufferView"),
            |d| {
                d.json["bufferViews"][0]["byteOffset"] = json!(1u64 << 40);
            },
        ),
        edited(
            "buffer byteLength 2⁶⁰",
            Expect::Refuse("buffer 0"),
            |d| {
                d.json["buffers"][0]["byteLength"] = json!(1u64 << 60);
            },
        ),
        edited(
            "buffer shorter than declared",
            Expect::Refuse("buffer 0"),
            |d| {
                d.json["buffers"][0]["byteLength"] = json!(d.bin.len() + 100);
            },
        ),
        edited("index out of range", Expect::Refuse("vertex"), |d| {
            let at = d.json["bufferViews"][2]["byteOffset"].as_u64().unwrap() as usize;
            d.bin[at] = 200;
        }),
        edited("NaN position", Expect::Refuse("non-finite"), |d| {
            d.bin[0..4].copy_from_slice(&f32::NAN.to_le_bytes());
        }),
        edited("position 1e30", Expect::Either, |d| {
            d.bin[0..4].copy_from_slice(&1e30f32.to_le_bytes());
        }),
        edited(
            "accessor index beyond the list",
            Expect::Refuse("accessor"),
            |d| {
                d.json["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(1_000_000);
            },
        ),
        edited(
            "material index beyond the list",
            Expect::Refuse("material"),
            |d| {
                d.json["meshes"][0]["primitives"][0]["material"] = json!(77);
            },
        ),
        edited("texture index beyond the list", Expect::Either, |d| {
            d.json["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"] =
                json!({ "index": 9 });
        }),
    ]
}

/// Node graphs: cycles, depth, and a small graph with 2⁴⁰ paths to one mesh.
pub fn graphs() -> Vec<Case> {
    vec![
        edited(
            "node DAG with 2⁴⁰ paths",
            Expect::Refuse("instances"),
            |d| {
                let mut nodes = vec![json!({ "name": "lamp", "translation": [0.3, 1.2, 0.2],
                "extensions": { "KHR_lights_punctual": { "light": 0 } } })];
                for level in 0..40 {
                    let next = 1 + 2 * (level + 1);
                    let children = if level < 39 {
                        json!([next, next + 1])
                    } else {
                        json!([])
                    };
                    let mesh = if level == 39 { json!(1) } else { json!(null) };
                    for k in 0..2 {
                        let mut n = json!({ "name": format!("n{level}_{k}"), "children": children,
                        "translation": [0.001, 0.0, 0.0] });
                        if !mesh.is_null() {
                            n["mesh"] = mesh.clone();
                        }
                        nodes.push(n);
                    }
                }
                d.json["nodes"] = json!(nodes);
                d.json["scenes"][0]["nodes"] = json!([0, 1, 2]);
            },
        ),
        edited("node cycle", Expect::Refuse("node"), |d| {
            d.json["nodes"][0]["children"] = json!([1]);
            d.json["nodes"][1]["children"] = json!([0]);
        }),
        edited("node chain 10⁴ deep", Expect::Refuse("node"), |d| {
            let mut nodes = vec![d.json["nodes"][2].clone()];
            for k in 0..10_000 {
                let mut n = json!({ "name": format!("c{k}") });
                if k + 1 < 10_000 {
                    n["children"] = json!([k + 2]);
                } else {
                    n["mesh"] = json!(0);
                }
                nodes.push(n);
            }
            d.json["nodes"] = json!(nodes);
            d.json["scenes"][0]["nodes"] = json!([0, 1]);
        }),
        edited("500 instances of the box", Expect::Bake, |d| {
            let nodes = d.json["nodes"].as_array_mut().unwrap();
            let first = nodes.len();
            for k in 0..500 {
                nodes.push(json!({ "name": format!("b{k}"), "mesh": 1,
                    "translation": [(k % 50) as f32 * 0.6, 0.0, (k / 50) as f32 * 0.6 + 2.0] }));
            }
            let roots: Vec<usize> = (0..3).chain(first..first + 500).collect();
            d.json["scenes"][0]["nodes"] = json!(roots);
        }),
        edited("2 000 point lights", Expect::Bake, |d| {
            let mut lights = Vec::new();
            let nodes = d.json["nodes"].as_array_mut().unwrap();
            let first = nodes.len();
            for k in 0..2000 {
                lights.push(json!({ "type": "point", "intensity": 0.01, "name": format!("l{k}") }));
                nodes.push(json!({ "translation": [(k % 40) as f32 * 0.05 - 1.0, 0.8, (k / 40) as f32 * 0.04 - 1.0],
                    "extensions": { "KHR_lights_punctual": { "light": k } } }));
            }
            d.json["extensions"]["KHR_lights_punctual"]["lights"] = json!(lights);
            let roots: Vec<usize> = (0..2).chain(first..first + 2000).collect();
            d.json["scenes"][0]["nodes"] = json!(roots);
        }),
        edited("light with intensity 1e38", Expect::Either, |d| {
            d.json["extensions"]["KHR_lights_punctual"]["lights"][0]["intensity"] = json!(1e38);
        }),
    ]
}

/// Malformed containers and documents.
pub fn malformed() -> Vec<Case> {
    let doc = Doc::base();
    let glb = doc.glb();
    let mut deep = String::new();
    for _ in 0..100_000 {
        deep.push('[');
    }
    let mut cases = vec![
        Case::bake(
            "valid GLB",
            vec![("scene.glb".into(), glb.clone())],
            Expect::Bake,
        ),
        Case::bake(
            "truncated GLB",
            vec![("scene.glb".into(), glb[..glb.len() / 2].to_vec())],
            Expect::Refuse("scene.glb"),
        ),
        Case::bake(
            "GLB with a chunk length of 2³² − 1",
            vec![("scene.glb".into(), {
                let mut g = glb.clone();
                g[12..16].copy_from_slice(&u32::MAX.to_le_bytes());
                g
            })],
            Expect::Refuse("scene.glb"),
        ),
        Case::bake(
            "JSON nested 10⁵ deep",
            vec![("scene.gltf".into(), deep.into_bytes())],
            Expect::Refuse("scene.gltf"),
        ),
        Case::bake(
            "invalid UTF-8",
            vec![("scene.gltf".into(), vec![b'{', 0xff, 0xfe, b'}'])],
            Expect::Refuse("scene.gltf"),
        ),
        Case::bake(
            "empty file",
            vec![("scene.gltf".into(), Vec::new())],
            Expect::Refuse("scene.gltf"),
        ),
        Case::bake(
            "no meshes",
            vec![(
                "scene.gltf".into(),
                br#"{"asset":{"version":"2.0"}}"#.to_vec(),
            )],
            Expect::Refuse("no triangles"),
        ),
    ];
    // A GLB whose image lives in an external file outside the folder.
    let mut g = Doc::base();
    g.texture_image(json!({ "uri": "../secret/secret.png" }));
    cases.push(Case::bake(
        "GLB with an image outside",
        vec![("scene.glb".into(), g.glb())],
        Expect::Refuse("secret.png"),
    ));
    cases.push(Case::bake(
        "a missing scene file",
        gltf_only(&doc),
        Expect::Refuse("nothing.gltf"),
    ));
    let last = cases.last_mut().unwrap();
    last.args[0] = "{scene}/nothing.gltf".into();
    cases
}

/// Large inputs (the ignored test, run by CI in release): each bakes in time that grows with
/// its size, within its time limit and the memory cap.
pub fn large() -> Vec<Case> {
    let auto = |name: &str, doc: Doc, timeout: f64| {
        let mut case = Case::bake(name, doc.files(), Expect::Bake);
        // The preset's texel budget decides the density.
        let at = case
            .args
            .iter()
            .position(|a| a == "--texel-density")
            .unwrap();
        case.args.drain(at..at + 2);
        case.timeout = timeout;
        case
    };
    let mut lights = Doc::base();
    {
        let mut list = Vec::new();
        let nodes = lights.json["nodes"].as_array_mut().unwrap();
        let first = nodes.len();
        for k in 0..100_000usize {
            list.push(json!({ "type": "point", "intensity": 0.001 }));
            nodes.push(json!({ "translation": [(k % 316) as f32 * 0.006 - 0.95, 0.6 + (k / 316) as f32 * 0.002, 0.9],
                "extensions": { "KHR_lights_punctual": { "light": k } } }));
        }
        lights.json["extensions"]["KHR_lights_punctual"]["lights"] = json!(list);
        let roots: Vec<usize> = (0..2).chain(first..first + 100_000).collect();
        lights.json["scenes"][0]["nodes"] = json!(roots);
    }
    let mut boxes = Doc::base();
    {
        let nodes = boxes.json["nodes"].as_array_mut().unwrap();
        let first = nodes.len();
        for k in 0..20_000 {
            nodes.push(json!({ "name": format!("b{k}"), "mesh": 1,
                "translation": [(k % 200) as f32 * 0.6, 0.0, (k / 200) as f32 * 0.6 + 2.0] }));
        }
        let roots: Vec<usize> = (0..3).chain(first..first + 20_000).collect();
        boxes.json["scenes"][0]["nodes"] = json!(roots);
    }
    vec![
        auto(
            "flat floor of 40 000 triangles",
            Doc::grid(200, 100, 1.0, 0.0),
            120.0,
        ),
        auto(
            "flat floor of 10⁶ triangles",
            Doc::grid(1000, 500, 0.2, 0.0),
            600.0,
        ),
        auto(
            "curved floor of 500 000 triangles",
            Doc::grid(500, 500, 0.2, 3.0),
            600.0,
        ),
        // A million loose charts need more than a 2048² page holds at 2 texels of padding.
        auto(
            "triangle soup of 10⁶ triangles",
            Doc::soup(1_000_000),
            600.0,
        )
        .with_args(&["--max-page-size", "8192"]),
        auto(
            "triangle soup of 10⁶ triangles, default page",
            Doc::soup(1_000_000),
            600.0,
        )
        .expecting(Expect::Refuse("--max-page-size")),
        auto("10⁵ point lights", lights, 600.0),
        auto("20 000 instances of the box", boxes, 600.0),
    ]
}

/// Standard base64 (with padding).
pub fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            if k <= c.len() {
                out.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}
