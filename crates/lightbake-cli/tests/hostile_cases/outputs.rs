//! Where a bake writes: onto its inputs, names that are not URIs, images that collide with
//! the bake's own files; and flags at their extremes.

use std::path::Path;

use serde_json::json;

use super::gltf::{Doc, png};
use super::{Case, Expect};

fn rename_scene(files: &mut [(String, Vec<u8>)], name: &str) {
    files[0].0 = name.to_string();
}

/// The output folder's files that must load again: baking the baked glTF succeeds.
fn rebake(case: &mut Case, baked: &str) {
    case.after.push(
        [
            &format!("{{out}}/{baked}"),
            "-o",
            "{root}/again",
            "--quality",
            "preview",
            "--threads",
            "1",
            "--texel-density",
            "8",
            "--quiet",
        ]
        .map(String::from)
        .to_vec(),
    );
}

/// The cases.
pub fn cases() -> Vec<Case> {
    let doc = Doc::base();
    let mut cases = Vec::new();
    cases.push(
        Case::bake(
            "-o the scene's own folder",
            doc.files(),
            Expect::Refuse("scene"),
        )
        .replacing_out("{scene}"),
    );
    cases.push(
        Case::bake("-o a folder inside the scene's", doc.files(), Expect::Bake)
            .replacing_out("{scene}/baked"),
    );
    let mut escaped = doc.files();
    rename_scene(&mut escaped, "a%41.gltf");
    let mut case = Case::bake("scene named a%41.gltf", escaped, Expect::Bake);
    rebake(&mut case, "a%41.gltf");
    cases.push(case);
    let mut odd = doc.files();
    rename_scene(&mut odd, "%FF #1?.gltf");
    let mut case = Case::bake("scene named %FF #1?.gltf", odd, Expect::Bake);
    rebake(&mut case, "%FF #1?.gltf");
    cases.push(case);
    // A scene image where the bake writes its first lightmap.
    let mut d = Doc::base();
    d.texture_image(json!({ "uri": "lightmaps/lightmap_0.exr", "mimeType": "image/png" }));
    let mut files = d.files();
    files.push(("lightmaps/lightmap_0.exr".into(), png(4, 4, [1, 2, 3, 255])));
    let mut case = Case::bake(
        "scene image at lightmaps/lightmap_0.exr",
        files,
        Expect::Bake,
    );
    case.checks.push(|root: &Path| {
        let bytes =
            std::fs::read(root.join("out/lightmaps/lightmap_0.exr")).map_err(|e| e.to_string())?;
        if bytes.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
            Ok(())
        } else {
            Err("lightmaps/lightmap_0.exr is not the baked EXR".into())
        }
    });
    rebake(&mut case, "scene.gltf");
    cases.push(case);
    // An image named like the baked glTF's buffer.
    let mut d = Doc::base();
    d.texture_image(json!({ "uri": "other.png" }));
    let mut files = d.files();
    files.push(("other.png".into(), png(4, 4, [1, 2, 3, 255])));
    let mut case = Case::bake("image copied beside the baked glTF", files, Expect::Bake);
    rebake(&mut case, "scene.gltf");
    cases.push(case);
    // Flags at their extremes.
    let flag = |name: &str, args: &[&str], expect: Expect| {
        let mut case = Case::bake(name, Doc::base().files(), expect);
        if args.contains(&"--texel-budget") {
            // The budget decides the density.
            let at = case
                .args
                .iter()
                .position(|a| a == "--texel-density")
                .unwrap();
            case.args.drain(at..at + 2);
        }
        case.with_args(args)
    };
    cases.extend([
        flag("--threads 100000", &["--threads", "100000"], Expect::Either),
        flag(
            "--threads 2⁶⁴ − 1",
            &["--threads", "18446744073709551615"],
            Expect::Either,
        ),
        flag(
            "--memory-budget 1",
            &["--memory-budget", "1"],
            Expect::Refuse("memory"),
        ),
        flag(
            "every ray count at its maximum",
            &[
                "--samples",
                "4096",
                "--sky-samples",
                "65536",
                "--transport-rays",
                "65536",
                "--cluster-rays",
                "65536",
                "--probe-rays",
                "65536",
                "--irradiance-volume",
                "--sky",
                "1,1,1",
                "--quality",
                "high",
                "--texel-budget",
                "100000000",
            ],
            Expect::Refuse("rays"),
        ),
        flag(
            "--texel-density 1e9",
            &["--texel-density", "1e9"],
            Expect::Refuse(""),
        ),
        flag("--sky NaN", &["--sky", "NaN,0,0"], Expect::Refuse("sky")),
        flag(
            "--vpl-particles max",
            &["--method", "vpl", "--vpl-particles", "4294967295"],
            Expect::Refuse(""),
        ),
        flag("--seed max", &["--seed", "4294967295"], Expect::Bake),
    ]);
    cases
}

impl Case {
    /// The same case writing to `out` (placeholders allowed) instead of `{out}`.
    pub fn replacing_out(mut self, out: &str) -> Self {
        if let Some(i) = self.args.iter().position(|a| a == "{out}") {
            self.args[i] = out.to_string();
        }
        self
    }
}
