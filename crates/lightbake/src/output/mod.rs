//! Writing a bake to disk: lightmap pages (EXR by default; HDR, KTX2 on request; a PNG
//! preview), the baked glTF, `manifest.json` and `report.json`, all staged to temporary files
//! and renamed into place together ([`atomic`]).
//!
//! Layout of an output directory:
//!
//! ```text
//! OUT_DIR/
//!   <scene>.gltf + <scene>.bin   (or <scene>.glb)   input + TEXCOORD_1 + node extras
//!   lightmaps/lightmap_<page>.exr|.hdr|.ktx2         E/π, linear RGB
//!   lightmaps/lightmap_<page>.preview.png            tonemapped, to look at
//!   manifest.json                                    instance → page file + uv_rect
//!   report.json                                      settings, plan, timings, rays, warnings
//! ```

pub mod atomic;
pub mod gltf_export;
pub mod images;

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::bake::BakeOutput;
use crate::error::{BakeError, Result};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use atomic::StagedFiles;

/// Version of the manifest format.
pub const MANIFEST_VERSION: u32 = 1;

/// Files of one atlas page, relative to the output directory.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PageFiles {
    /// Page index.
    pub index: u32,
    /// Texels across.
    pub width: u32,
    /// Texels down.
    pub height: u32,
    /// OpenEXR file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub exr: Option<String>,
    /// Radiance HDR file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub hdr: Option<String>,
    /// KTX2 file, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ktx2: Option<String>,
    /// Tonemapped PNG preview, if written.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub preview: Option<String>,
}

impl PageFiles {
    /// The file a game should load (EXR, else KTX2, else HDR).
    pub fn primary(&self) -> Option<&str> {
        self.exr
            .as_deref()
            .or(self.ktx2.as_deref())
            .or(self.hdr.as_deref())
    }
}

/// One baked instance in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ManifestInstance {
    /// Instance name (glTF node name, `#primitive` appended when the mesh has several).
    pub name: String,
    /// glTF node index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub node: Option<usize>,
    /// glTF mesh index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mesh: Option<usize>,
    /// glTF primitive index.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub primitive: Option<usize>,
    /// Page index.
    pub page: u32,
    /// The page's primary image, relative to the output directory.
    pub image: String,
    /// Bevy's `Lightmap::uv_rect`: [min u, min v, max u, max v] on the page.
    pub uv_rect: [f32; 4],
    /// The rectangle in texels: [x, y, width, height].
    pub rect: [u32; 4],
    /// Texels per metre achieved on the mesh's largest instance.
    pub texel_density: f32,
    /// `xatlas` or `existing` (the mesh's own TEXCOORD_1).
    pub uv_source: crate::unwrap::UvOrigin,
}

/// `manifest.json`: what a game needs to attach the lightmaps.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Manifest {
    /// Always `lightbake-manifest`.
    pub format: &'static str,
    /// [`MANIFEST_VERSION`].
    pub version: u32,
    /// The source scene file name.
    pub scene: String,
    /// The baked glTF, relative to the output directory.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub baked_gltf: Option<String>,
    /// What the texels hold.
    pub stored_quantity: &'static str,
    /// Pages.
    pub pages: Vec<PageFiles>,
    /// Baked instances.
    pub instances: Vec<ManifestInstance>,
}

/// What [`write_outputs`] wrote.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Written {
    /// Every file, absolute or relative to where the output directory was given.
    pub files: Vec<PathBuf>,
    /// Texel channels clamped to the half-float range (65504).
    pub clamped_channels: usize,
}

fn encode_err(path: &Path) -> impl FnOnce(String) -> BakeError + '_ {
    move |message| BakeError::Encode {
        path: path.to_path_buf(),
        message,
    }
}

/// Page file names without the output directory.
pub fn page_files(output: &BakeOutput, settings: &BakeSettings) -> Vec<PageFiles> {
    output
        .pages
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let f = |ext: &str, on: bool| on.then(|| format!("lightmaps/lightmap_{i}.{ext}"));
            PageFiles {
                index: i as u32,
                width: p.width,
                height: p.height,
                exr: f("exr", settings.formats.exr),
                hdr: f("hdr", settings.formats.hdr),
                ktx2: f("ktx2", settings.formats.ktx2),
                preview: f("preview.png", settings.formats.png_preview),
            }
        })
        .collect()
}

/// The manifest of a bake.
pub fn manifest(
    output: &BakeOutput,
    original: &Scene,
    pages: &[PageFiles],
    baked_gltf: Option<String>,
) -> Manifest {
    let mut instances = Vec::new();
    for (i, inst) in original.instances.iter().enumerate() {
        let Some(rect) = output.layout.instances[i] else {
            continue;
        };
        let unwrap = output.layout.meshes[inst.mesh]
            .as_ref()
            .expect("rect implies unwrap");
        let source = original.meshes[inst.mesh].source;
        instances.push(ManifestInstance {
            name: inst.name.clone(),
            node: inst.gltf_node,
            mesh: source.map(|s| s.mesh),
            primitive: source.map(|s| s.primitive),
            page: rect.page,
            image: pages[rect.page as usize]
                .primary()
                .unwrap_or_default()
                .to_string(),
            uv_rect: rect.uv_rect(output.layout.pages[rect.page as usize]),
            rect: [rect.x, rect.y, rect.width, rect.height],
            texel_density: unwrap.texels_per_metre,
            uv_source: unwrap.origin,
        });
    }
    Manifest {
        format: "lightbake-manifest",
        version: MANIFEST_VERSION,
        scene: original.name.clone(),
        baked_gltf,
        stored_quantity: "irradiance / pi (lux / pi), linear RGB; Bevy: Lightmap with lightmap_exposure = 1",
        pages: pages.to_vec(),
        instances,
    }
}

/// Writes every output of a bake into `dir` (created if needed). `source` is the glTF the
/// scene came from; without it no baked glTF is written. Nothing in `dir` changes unless all
/// files were encoded and staged successfully.
///
/// # Errors
/// [`BakeError::Write`] / [`BakeError::Encode`] naming the file.
pub fn write_outputs(
    dir: &Path,
    output: &BakeOutput,
    original: &Scene,
    source: Option<&crate::scene::gltf_import::GltfSource>,
    settings: &BakeSettings,
) -> Result<Written> {
    let mut staged = StagedFiles::new();
    let mut clamped = 0;
    let pages = page_files(output, settings);
    for (page, files) in output.pages.iter().zip(&pages) {
        clamped += images::count_over_half_range(page);
        if let Some(f) = &files.exr {
            let path = dir.join(f);
            let bytes = images::encode_exr(page).map_err(encode_err(&path))?;
            staged.stage(&path, &bytes)?;
        }
        if let Some(f) = &files.hdr {
            let path = dir.join(f);
            let bytes = images::encode_hdr(page).map_err(encode_err(&path))?;
            staged.stage(&path, &bytes)?;
        }
        if let Some(f) = &files.ktx2 {
            staged.stage(&dir.join(f), &images::encode_ktx2(page))?;
        }
        if let Some(f) = &files.preview {
            let path = dir.join(f);
            let bytes = images::encode_preview_png(page).map_err(encode_err(&path))?;
            staged.stage(&path, &bytes)?;
        }
    }
    let mut baked_gltf = None;
    if let Some(source) = source {
        let stem = source
            .path
            .file_stem()
            .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
        let mut node_lightmaps = Vec::new();
        for (i, inst) in original.instances.iter().enumerate() {
            let (Some(rect), Some(node), Some(src)) = (
                output.layout.instances[i],
                inst.gltf_node,
                original.meshes[inst.mesh].source,
            ) else {
                continue;
            };
            node_lightmaps.push(gltf_export::NodeLightmap {
                node,
                primitive: src.primitive,
                page: rect.page,
                image: pages[rect.page as usize]
                    .primary()
                    .unwrap_or_default()
                    .to_string(),
                uv_rect: rect.uv_rect(output.layout.pages[rect.page as usize]),
            });
        }
        let baked =
            gltf_export::baked_gltf(source, original, &output.layout, &node_lightmaps, &stem)?;
        for (rel, bytes) in &baked.files {
            staged.stage(&dir.join(rel), bytes)?;
        }
        baked_gltf = baked
            .files
            .iter()
            .map(|(p, _)| p.to_string_lossy().into_owned())
            .find(|p| p.ends_with(".gltf") || p.ends_with(".glb"));
    }
    let manifest = manifest(output, original, &pages, baked_gltf);
    let manifest_path = dir.join("manifest.json");
    let text = serde_json::to_vec_pretty(&manifest)
        .map_err(|e| encode_err(&manifest_path)(e.to_string()))?;
    staged.stage(&manifest_path, &text)?;

    let mut report = output.report.clone();
    report.outputs = staged
        .destinations()
        .chain(std::iter::once(dir.join("report.json").as_path()))
        .map(|p| {
            p.strip_prefix(dir)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    if clamped > 0 {
        report.warnings.push(format!(
            "{clamped} texel channels exceed the half-float maximum 65504 and were clamped in EXR/KTX2 output"
        ));
    }
    let report_path = dir.join("report.json");
    let text =
        serde_json::to_vec_pretty(&report).map_err(|e| encode_err(&report_path)(e.to_string()))?;
    staged.stage(&report_path, &text)?;
    let files = staged.commit()?;
    Ok(Written {
        files,
        clamped_channels: clamped,
    })
}
