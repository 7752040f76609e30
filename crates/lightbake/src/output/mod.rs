//! Writing a bake to disk: lightmap pages (EXR by default; HDR, KTX2 on request; a PNG
//! preview), the baked glTF, `manifest.json` and `report.json`, all staged to temporary files
//! and renamed into place together ([`crate::atomic`]).
//!
//! Layout of an output directory:
//!
//! ```text
//! OUT_DIR/
//!   <scene>.gltf + <scene>.bin   (or <scene>.glb)   input + TEXCOORD_1 + node extras
//!   lightmaps/lightmap_<page>.exr|.hdr|.ktx2         E/π, linear RGB
//!   lightmaps/lightmap_<page>.bc6h.ktx2              the same in BC6H blocks (on request)
//!   lightmaps/lightmap_<page>.preview.png            tonemapped, to look at
//!   lightmaps/groups/<group>/lightmap_<page>.*       each light group's pages (with groups)
//!   irradiance_volumes/volume_0.ktx2                 ambient cubes for dynamic objects (on request)
//!   irradiance_volumes/groups/<group>/volume_0.ktx2  each light group's volume
//!   manifest.json                                    instance → page file + uv_rect
//!   report.json                                      settings, plan, timings, rays, warnings
//!   lightbake.cache                                  what the next bake into the folder follows
//! ```

internal!(drawable, gltf_export, images);
pub mod bc6h;
pub mod manifest;

use std::path::{Path, PathBuf};

use crate::atomic::StagedFiles;
use crate::bake::BakeOutput;
use crate::error::{BakeError, Result};
use crate::incremental::{CACHE_FILE, PARTIAL_FILE};
use crate::lightmap::LightmapPage;
use crate::scene::Scene;
use crate::scene::extras::{GroupExtras, NodeLightmap, SceneExtras};
use crate::scene::gltf_import::GltfSource;
use crate::settings::BakeSettings;
pub use manifest::{
    MANIFEST_VERSION, Manifest, ManifestGroup, ManifestInstance, ManifestVolume, PageFiles,
    group_volume_file, manifest, volume_file, volumes,
};

/// What [`write_outputs`] wrote.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Written {
    /// Every file, absolute or relative to where the output directory was given.
    pub files: Vec<PathBuf>,
    /// Per BC6H page written, what the compression changed (empty without BC6H pages).
    pub bc6h: Vec<bc6h::Bc6hError>,
    /// Page and volume files an earlier bake into the folder wrote and this one did not
    /// (fewer pages, volumes or groups, other formats), removed so that no stale image lies
    /// beside the ones the manifest and glTF list.
    pub removed: Vec<PathBuf>,
    /// The baked glTF's primitives given a `TEXCOORD_0` (their `TEXCOORD_1`'s accessor),
    /// without which Bevy's `StandardMaterial` shader fails for a lightmapped mesh; as
    /// `mesh 'NAME' primitive P`. Also in the report
    /// ([`BakeReport::texcoord_0_added`](crate::report::BakeReport::texcoord_0_added)).
    pub texcoord_0_added: Vec<String>,
    /// Why parts of the baked glTF draw other than as baked in Bevy (one line each; also
    /// among the report's warnings).
    pub warnings: Vec<String>,
}

fn encode_err(path: &Path) -> impl FnOnce(String) -> BakeError + '_ {
    move |message| BakeError::Encode {
        path: path.to_path_buf(),
        message,
    }
}

/// Page file names without the output directory.
pub fn page_files(output: &BakeOutput, settings: &BakeSettings) -> Vec<PageFiles> {
    files_of(&output.pages, "lightmaps", settings)
}

/// Each light group's page file names without the output directory
/// (`lightmaps/groups/<group>/`), in the order of [`BakeOutput::groups`].
pub fn group_page_files(output: &BakeOutput, settings: &BakeSettings) -> Vec<Vec<PageFiles>> {
    (output.groups.iter())
        .map(|g| files_of(&g.pages, &format!("lightmaps/groups/{}", g.name), settings))
        .collect()
}

/// The file names of `pages` in folder `folder`.
fn files_of(pages: &[LightmapPage], folder: &str, settings: &BakeSettings) -> Vec<PageFiles> {
    pages
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let f = |ext: &str, on: bool| on.then(|| format!("{folder}/lightmap_{i}.{ext}"));
            PageFiles {
                index: i as u32,
                width: p.width,
                height: p.height,
                exr: f("exr", settings.formats.exr),
                hdr: f("hdr", settings.formats.hdr),
                ktx2: f("ktx2", settings.formats.ktx2),
                ktx2_bc6h: f("bc6h.ktx2", settings.formats.ktx2_bc6h),
                preview: f("preview.png", settings.formats.png_preview),
            }
        })
        .collect()
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
    source: Option<&GltfSource>,
    settings: &BakeSettings,
) -> Result<Written> {
    if let Some(source) = source {
        refuse_own_folder(dir, source)?;
    }
    let mut staged = StagedFiles::new(dir);
    let pages = page_files(output, settings);
    let group_pages = group_page_files(output, settings);
    let compressed = stage_pages(&mut staged, dir, &output.pages, &pages, true)?;
    for (g, files) in output.groups.iter().zip(&group_pages) {
        stage_pages(&mut staged, dir, &g.pages, files, false)?;
    }
    let volumes = (output.irradiance_volumes.iter().enumerate())
        .map(|(i, v)| (v, volume_file(i)))
        .chain(output.groups.iter().flat_map(|g| {
            (g.irradiance_volumes.iter().enumerate())
                .map(|(i, v)| (v, group_volume_file(&g.name, i)))
        }));
    for (volume, file) in volumes {
        let (size, texels) = volume.texture();
        if texels.iter().any(|t| !t.is_finite()) {
            return Err(encode_err(&dir.join(&file))(
                "a probe holds a non-finite value; nothing was written".into(),
            ));
        }
        let bytes = images::encode_ktx2_texels(size.to_array(), &texels);
        staged.stage(&dir.join(&file), &bytes)?;
    }
    let baked_gltf = match source {
        Some(source) => Some(stage_baked_gltf(
            &mut staged,
            dir,
            output,
            original,
            source,
            (&pages, &group_pages),
        )?),
        None => None,
    };
    let (gltf_name, texcoord_0_added, warnings) = match baked_gltf {
        Some((name, added, warnings)) => (Some(name), added, warnings),
        None => Default::default(),
    };
    let manifest = manifest(output, original, (&pages, &group_pages), gltf_name);
    stage_json(&mut staged, &dir.join("manifest.json"), &manifest)?;
    if let Some(cache) = &output.cache {
        staged.stage(&dir.join(CACHE_FILE), &cache.to_bytes())?;
    }
    let mut report = output.report.clone();
    report.texcoord_0_added = texcoord_0_added.clone();
    report.warnings.extend(warnings.iter().cloned());
    let report_path = dir.join("report.json");
    report.outputs = staged
        .destinations()
        .chain(std::iter::once(report_path.as_path()))
        .map(|p| {
            p.strip_prefix(dir)
                .unwrap_or(p)
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    // What an earlier bake into `dir` wrote and this one does not: read before the new
    // report replaces the old one, removed once the new files are in place.
    let stale = stale_outputs(dir, &report.outputs);
    stage_json(&mut staged, &report_path, &report)?;
    if let Some(source) = source {
        for dest in staged.destinations() {
            if let Some(input) = source.inputs.iter().find(|i| same_file(dest, i)) {
                return Err(BakeError::OverwritesInput {
                    output: dest.to_path_buf(),
                    input: input.clone(),
                });
            }
        }
    }
    // Named as the caller named the folder.
    let root = crate::atomic::normalized(dir).unwrap_or_else(|_| dir.to_path_buf());
    let files = staged
        .commit()?
        .into_iter()
        .map(|p| p.strip_prefix(&root).map_or(p.clone(), |rel| dir.join(rel)))
        .collect();
    let mut removed: Vec<PathBuf> = (stale.into_iter())
        .filter(|p| std::fs::remove_file(p).is_ok())
        .collect();
    // The finished bake's cache supersedes the checkpoints of an unfinished one (a file of
    // that name only, not a link or a folder).
    let partial = dir.join(PARTIAL_FILE);
    if std::fs::symlink_metadata(&partial).is_ok_and(|m| m.is_file())
        && std::fs::remove_file(&partial).is_ok()
    {
        removed.push(partial);
    }
    // And the files a bake killed while writing one left (`incremental::write_partial`).
    for entry in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let unfinished = entry
            .file_name()
            .to_string_lossy()
            .starts_with(".lightbake.partial.");
        if unfinished && entry.file_type().is_ok_and(|t| t.is_file()) {
            let _ = std::fs::remove_file(entry.path());
        }
    }
    for p in &removed {
        // The folders a removed file leaves empty (a group's, `groups/`, `irradiance_volumes/`)
        // go too; `remove_dir` takes only empty ones.
        for folder in p.ancestors().skip(1).take_while(|a| *a != dir) {
            if std::fs::remove_dir(folder).is_err() {
                break;
            }
        }
    }
    Ok(Written {
        files,
        bc6h: compressed,
        removed,
        texcoord_0_added,
        warnings,
    })
}

/// The page and volume files an earlier bake into `dir` wrote (its `report.json`'s
/// `outputs`) that this one does not (`kept`, relative to `dir`): after a rebake with fewer
/// pages, volumes or groups, or other formats, they would lie beside the files the new
/// manifest and glTF list; and an earlier bake's cache a bake that keeps none leaves (it
/// would follow a bake older than the outputs). Only regular files named as the bake names
/// pages and volumes (`lightmaps/[groups/G/]lightmap_N.*`,
/// `irradiance_volumes/[groups/G/]volume_N.ktx2`) and its cache (`lightbake.cache`) inside
/// `dir` are taken; an earlier report that cannot be read gives none.
fn stale_outputs(dir: &Path, kept: &[String]) -> Vec<PathBuf> {
    #[derive(serde::Deserialize)]
    struct Earlier {
        #[serde(default)]
        outputs: Vec<String>,
    }
    let Ok(text) = std::fs::read(dir.join("report.json")) else {
        return Vec::new();
    };
    let Ok(earlier) = serde_json::from_slice::<Earlier>(&text) else {
        return Vec::new();
    };
    let Ok(root) = dir.canonicalize() else {
        return Vec::new();
    };
    // Not through a linked folder that leads out of `dir`.
    let inside = |p: &Path| {
        (p.parent().and_then(|d| d.canonicalize().ok())).is_some_and(|d| d.starts_with(&root))
    };
    (earlier.outputs.iter())
        .filter(|f| (is_page_or_volume_file(f) || *f == CACHE_FILE) && !kept.contains(f))
        .map(|f| dir.join(f))
        .filter(|p| std::fs::symlink_metadata(p).is_ok_and(|m| m.is_file()) && inside(p))
        .collect()
}

/// Whether `rel` is named as the bake names a page or volume file (see [`stale_outputs`]).
fn is_page_or_volume_file(rel: &str) -> bool {
    let parts: Vec<&str> = rel.split('/').collect();
    let plain = |s: &str| !s.is_empty() && s != "." && s != ".." && !s.contains(['\\', ':', '\0']);
    if !parts.iter().all(|s| plain(s)) {
        return false;
    }
    let numbered = |name: &str, stem: &str, exts: &[&str]| {
        name.strip_prefix(stem)
            .and_then(|rest| rest.split_once('.'))
            .is_some_and(|(n, ext)| {
                !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()) && exts.contains(&ext)
            })
    };
    let (folder, name) = match parts.as_slice() {
        [folder, name] | [folder, "groups", _, name] => (*folder, *name),
        _ => return false,
    };
    match folder {
        "lightmaps" => numbered(
            name,
            "lightmap_",
            &["exr", "hdr", "ktx2", "bc6h.ktx2", "preview.png"],
        ),
        "irradiance_volumes" => numbered(name, "volume_", &["ktx2"]),
        _ => false,
    }
}

/// Refuses an output folder that is the scene's own (its outputs would sit among, and may
/// replace, the scene's files).
fn refuse_own_folder(dir: &Path, source: &GltfSource) -> Result<()> {
    let scene_dir = match source.path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if let (Ok(a), Ok(b)) = (dir.canonicalize(), scene_dir.canonicalize())
        && a == b
    {
        return Err(BakeError::OverwritesInput {
            output: dir.to_path_buf(),
            input: scene_dir.to_path_buf(),
        });
    }
    Ok(())
}

/// Whether `a` and `b` are the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}

/// Stages every page in every format asked for; returns what BC6H did to each page written as
/// BC6H (when `measure`).
fn stage_pages(
    staged: &mut StagedFiles,
    dir: &Path,
    pages: &[LightmapPage],
    files: &[PageFiles],
    measure: bool,
) -> Result<Vec<bc6h::Bc6hError>> {
    use rayon::prelude::*;
    // One file of one page: its path, the page and its format.
    let mut jobs: Vec<(PathBuf, &LightmapPage, &str)> = Vec::new();
    for (page, files) in pages.iter().zip(files) {
        // A lightmap never holds a NaN or an infinity (every stage checks its output; this is
        // the last line).
        if let Some(k) = page.texels.iter().position(|t| !t.is_finite()) {
            let path = dir.join(files.primary().unwrap_or_default());
            return Err(encode_err(&path)(format!(
                "texel ({}, {}) holds the non-finite value {:?}; nothing was written",
                k as u32 % page.width,
                k as u32 / page.width,
                page.texels[k]
            )));
        }
        let formats = [
            (&files.exr, "exr"),
            (&files.hdr, "hdr"),
            (&files.ktx2, "ktx2"),
            (&files.ktx2_bc6h, "bc6h"),
            (&files.preview, "png"),
        ];
        for (file, format) in formats {
            if let Some(f) = file {
                jobs.push((dir.join(f), page, format));
            }
        }
    }
    // A set of pages' files encoded in parallel (the bake's own, or one light group's: the
    // encoded bytes held at once are one set's), then staged in order.
    let encoded: Vec<(Vec<u8>, Option<bc6h::Bc6hError>)> = (jobs.par_iter())
        .map(|(path, page, format)| {
            let bytes = match *format {
                "exr" => images::encode_exr(page),
                "hdr" => images::encode_hdr(page),
                "ktx2" => Ok(images::encode_ktx2(page)),
                "bc6h" => bc6h::encode_ktx2_bc6h(page),
                _ => images::encode_preview_png(page),
            }
            .map_err(encode_err(path))?;
            let measured = (measure && *format == "bc6h")
                .then(|| bc6h::measure(page, &bytes).map_err(encode_err(path)))
                .transpose()?;
            Ok((bytes, measured))
        })
        .collect::<Result<_>>()?;
    let mut compressed = Vec::new();
    for ((path, _, _), (bytes, measured)) in jobs.iter().zip(encoded) {
        staged.stage(path, &bytes)?;
        compressed.extend(measured);
    }
    Ok(compressed)
}

/// Stages the baked glTF (and its buffer and images); returns its file name, the primitives
/// given a `TEXCOORD_0` and the warnings on what Bevy draws other than as baked.
fn stage_baked_gltf(
    staged: &mut StagedFiles,
    dir: &Path,
    output: &BakeOutput,
    original: &Scene,
    source: &GltfSource,
    (pages, group_pages): (&[PageFiles], &[Vec<PageFiles>]),
) -> Result<(String, Vec<String>, Vec<String>)> {
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
        let files = &pages[rect.page as usize];
        let lightmap = NodeLightmap {
            primitive: src.primitive,
            page: rect.page,
            image: files.primary().unwrap_or_default().to_string(),
            image_bc6h: files.bc6h_besides_primary().map(str::to_string),
            uv_rect: rect.uv_rect(output.layout.pages[rect.page as usize]),
        };
        node_lightmaps.push((node, lightmap));
    }
    // The other outputs' names: pages and volumes staged so far, the manifest and report.
    let reserved: Vec<String> = staged
        .destinations()
        .filter_map(|p| p.strip_prefix(dir).ok())
        .map(|p| p.to_string_lossy().replace('\\', "/"))
        .chain(["manifest.json".to_string(), "report.json".to_string()])
        .collect();
    let written = SceneExtras {
        irradiance_volumes: volumes(output),
        light_groups: (manifest::groups(output, group_pages).into_iter())
            .map(|g| GroupExtras {
                name: g.name,
                members: g.members,
                pages: (g.pages.iter())
                    .map(|p| p.primary().unwrap_or_default().to_string())
                    .collect(),
                pages_bc6h: (g.pages.iter())
                    .map(|p| p.bc6h_besides_primary().map(str::to_string))
                    .collect::<Option<Vec<_>>>()
                    .unwrap_or_default(),
                irradiance_volumes: g.irradiance_volumes,
            })
            .collect(),
        ..SceneExtras::default()
    };
    let baked = gltf_export::baked_gltf(
        source,
        original,
        &output.layout,
        &node_lightmaps,
        &written,
        &stem,
        &reserved,
    )?;
    for (rel, bytes) in &baked.files {
        staged.stage(&dir.join(rel), bytes)?;
    }
    let name = (baked.files.iter())
        .map(|(p, _)| p.to_string_lossy().into_owned())
        .find(|p| p.ends_with(".gltf") || p.ends_with(".glb"))
        .unwrap_or_default();
    Ok((name, baked.texcoord_0_added, baked.warnings))
}

/// Stages `value` as pretty-printed JSON at `path`.
fn stage_json(staged: &mut StagedFiles, path: &Path, value: &impl serde::Serialize) -> Result<()> {
    let text = serde_json::to_vec_pretty(value).map_err(|e| encode_err(path)(e.to_string()))?;
    staged.stage(path, &text)
}
