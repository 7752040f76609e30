//! Incremental bakes: what a bake keeps for the next bake of the same scene, what an edit
//! changed, and how far each texel's light can move because of it.
//!
//! A bake run through the runner's subset scope (`bake::TexelRun`) keeps, beside its outputs,
//! a [`BakeCache`] (`OUT/lightbake.cache`): the settings, the texel density, hashes of every
//! input part ([`SceneHashes`]: meshes, instances, surfaces, lights, sky), each instance's box
//! and emission, the lights as they were, the lightmap layout, and every split stage's values
//! keyed by texel patch ([`StageValues`]). The next bake into OUT reads it back
//! ([`read_cache`]) and [`plan`]s:
//!
//! * **full**, with the reason, when there is no usable cache (none, damaged, truncated, from
//!   another baker version or another scene), when the settings that decide the texels
//!   changed, with a target error, or when asked (`--full`); with light groups, for every edit
//!   but a change of their lights' colour or intensity;
//! * **relit** ([`Relighting`]), with light groups, when the edit changes only the colour or
//!   intensity of lights or the sky, by one factor per channel within each group: the
//!   weighted sum of the cached groups' pages ([`relight`], [`KeptGroups`]), nothing lit;
//! * else an **edit** ([`Edits`]): the layout of the meshes that did not change is kept
//!   (`unwrap::stable`), and each split stage recomputes only the items whose inputs moved,
//!   relative to their earlier level, by more than [`SHARE`] of the earlier bake's estimated
//!   error: for the direct light the bound of `bounds` (lights changed, shadows cast or
//!   lifted, emission, sky), for the gathers the change of the coarse light each node
//!   gathers, which the pass states. Every other item keeps its value, and a recomputed item
//!   is computed exactly as a full bake of the edited scene computes it (random numbers are
//!   keyed by texel, sample and seed).
//!
//! What each stage reads is declared beside its name ([`crate::stage::Stage::reads`]: parts
//! of the input, earlier stages' outputs, and whether its output is kept item by item, whole,
//! or not at all); [`Edits::changed`] names the parts an edit changed, and a stage none of
//! whose reads changed keeps its output. The runner seam applies this
//! (`runner::WorkScope::split`, `runner::WorkScope::kept_across_edits`): a pass states its
//! items, the patch each belongs to and, where it knows it, one number summing up what the
//! item reads; a split stage that states no summary (and is not the direct light) is computed
//! whole. The texel patches are kept whole (with the hash of the geometry and layout they
//! were made from, `patch_geometry`, checked again). Three whole stages keep what reads only
//! the geometry and layout as a [`KeptState`] (`runner::WorkScope::keep_state`: bytes under
//! the pass's own key, with their checksum) and bring the rest up to date: the nodes their
//! basis areas (their albedo made again), the coarse level its cut and matrix (its first
//! bounce updated by shooting from the nodes whose reflected direct light changed:
//! `radiosity::coarse_kept`), the contact fit its samples (its fit made again). The passes
//! whose output the cache does not hold (the denoiser, the grid error, the stitch) run
//! whole.
//!
//! A bake that keeps checkpoints ([`crate::bake::BakeBuilder::checkpoints`]) computes each
//! split stage's items in blocks and hands over, every few seconds (at least 2 s, and 19
//! times the last checkpoint's writing time), the stage so far: its finished items
//! ([`KeptStage::finished`]). A bake that resumes from it computes only the
//! unfinished ones.

mod bounds;
pub(crate) mod codec;
mod edits;
mod relight;
mod values;

use std::path::Path;

use glam::{Vec2, Vec3};
use serde::Serialize;

pub(crate) use bounds::direct_bounds;
use codec::{Bad, Reader, Writer};
pub use edits::{Aabb, Edits, Emitter, deciding_settings, edits, instance_boxes};
pub use relight::{KeptGroup, KeptGroups, KeptPage, Relit, relight};
pub use values::{KeptStage, KeptState, StageValues};
pub(crate) use values::{patch_geometry, patch_keys};

use crate::scene::hashes::{InstanceHashes, SceneHashes};
use crate::scene::{Light, Scene};
use crate::settings::BakeSettings;
use crate::stage::{Input, Kept, Stage};
use crate::unwrap::{InstanceRect, Layout, MeshUnwrap, PageSize, UvOrigin};

/// The cache's file name in the output folder.
pub const CACHE_FILE: &str = "lightbake.cache";

/// The file name, in the output folder, of the cache of a bake that has not finished: written
/// after each split stage ([`crate::bake::BakeBuilder::checkpoints`]), removed when the bake's
/// outputs are in place.
pub const PARTIAL_FILE: &str = "lightbake.partial";

/// What a bake keeps for the next bake of the same scene.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeCache {
    /// The settings it baked with.
    pub settings: BakeSettings,
    /// The texel density its layout was made at, texels per metre.
    pub density: f32,
    /// Hashes of the scene's parts.
    pub scene: SceneHashes,
    /// Each instance's name (for messages about removed ones).
    pub instance_names: Vec<String>,
    /// Each instance's world box and emitted luminance.
    pub boxes: Vec<Emitter>,
    /// The lights as they were.
    pub lights: Vec<Light>,
    /// The sky as it was, nits.
    pub sky: Vec3,
    /// The lightmap layout.
    pub layout: Layout,
    /// Per mesh of the layout, the texels per mesh unit its unwrap was made for.
    pub requests: Vec<f32>,
    /// The split stages' values.
    pub values: StageValues,
    /// The bake's estimated error, relative RMS (0 when it had none): an item whose inputs
    /// move by less than [`SHARE`] of it keeps its value.
    pub error: f32,
    /// With light groups: each group's finished pages and estimate, which a later bake
    /// relights ([`relight`]). Empty without groups.
    pub groups: KeptGroups,
}

impl BakeCache {
    /// What a bake of `scene` with `settings` at `density` over `layout` keeps, with its split
    /// stages' `values`.
    pub fn new(
        scene: &Scene,
        settings: &BakeSettings,
        density: f32,
        layout: &Layout,
        values: StageValues,
        error: f32,
    ) -> Self {
        Self {
            settings: settings.clone(),
            density,
            scene: SceneHashes::of(scene),
            instance_names: scene.instances.iter().map(|i| i.name.clone()).collect(),
            boxes: instance_boxes(scene),
            lights: scene.lights.clone(),
            sky: scene.sky,
            layout: layout.clone(),
            requests: crate::unwrap::stable::mesh_requests(scene, density),
            values,
            error: if error.is_finite() {
                error.max(0.0)
            } else {
                0.0
            },
            groups: KeptGroups::default(),
        }
    }

    /// The cache with the light groups' pages and estimates a later bake relights.
    pub fn with_groups(mut self, groups: KeptGroups) -> Self {
        self.groups = groups;
        self
    }

    /// The cache file's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = Writer::default();
        w.bytes(&serde_json::to_vec(&self.settings).unwrap_or_default());
        w.f32(self.density);
        write_hashes(&mut w, &self.scene);
        w.len(self.instance_names.len());
        for (name, ((lo, hi), lum)) in self.instance_names.iter().zip(&self.boxes) {
            w.str(name);
            w.f32s(&[lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, *lum]);
        }
        w.bytes(&serde_json::to_vec(&self.lights).unwrap_or_default());
        w.f32s(&self.sky.to_array());
        write_layout(&mut w, &self.layout);
        w.f32s(&self.requests);
        self.values.write(&mut w);
        w.f32(self.error);
        self.groups.write(&mut w);
        w.finish(env!("CARGO_PKG_VERSION"))
    }

    /// The cache a file's bytes hold.
    ///
    /// # Errors
    /// Why it cannot be used, in words: another baker version or format, damaged, truncated
    /// or inconsistent.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, String> {
        let mut r = Reader::open(bytes, env!("CARGO_PKG_VERSION"))?;
        let settings = serde_json::from_slice(r.bytes()?)
            .map_err(|e| format!("its settings do not read: {e}"))?;
        let density = r.f32()?;
        let scene = read_hashes(&mut r)?;
        let n = r.len(8)?;
        let mut instance_names = Vec::with_capacity(n);
        let mut boxes = Vec::with_capacity(n);
        for _ in 0..n {
            instance_names.push(r.str()?);
            let b = r.f32s()?;
            let [x0, y0, z0, x1, y1, z1, lum] = b[..] else {
                return Err("an instance's box does not read".into());
            };
            boxes.push(((Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1)), lum));
        }
        let lights: Vec<Light> = serde_json::from_slice(r.bytes()?)
            .map_err(|e| format!("its lights do not read: {e}"))?;
        let sky = r.f32s()?;
        let [sx, sy, sz] = sky[..] else {
            return Err("its sky does not read".into());
        };
        let layout = read_layout(&mut r)?;
        let requests = r.f32s()?;
        let values = StageValues::read(&mut r)?;
        let error = r.f32()?;
        let groups = KeptGroups::read(&mut r)?;
        r.end()?;
        let pages_fit = (groups.groups.iter()).all(|g| {
            g.pages.len() == layout.pages.len()
                && (g.pages.iter().zip(&layout.pages))
                    .all(|(p, s)| p.width == s.width && p.height == s.height)
        });
        let consistent = scene.instances.len() == n
            && scene.lights.len() == lights.len()
            && layout.instances.len() == n
            && layout.meshes.len() == scene.meshes.len()
            && requests.len() == scene.meshes.len()
            && layout.validate().is_ok()
            && error.is_finite()
            && error >= 0.0
            && pages_fit;
        if !consistent {
            return Err("its parts do not agree with each other".into());
        }
        Ok(Self {
            settings,
            density,
            scene,
            instance_names,
            boxes,
            lights,
            sky: Vec3::new(sx, sy, sz),
            layout,
            requests,
            values,
            error,
            groups,
        })
    }
}

fn write_hashes(w: &mut Writer, h: &SceneHashes) {
    w.u64s(&h.meshes);
    w.len(h.instances.len());
    for i in &h.instances {
        for v in [i.identity, i.geometry, i.placement, i.albedo, i.emission] {
            w.u64(v);
        }
    }
    let (ids, content): (Vec<u64>, Vec<u64>) = h.lights.iter().copied().unzip();
    w.u64s(&ids);
    w.u64s(&content);
    w.u64(h.sky);
}

fn read_hashes(r: &mut Reader<'_>) -> Result<SceneHashes, Bad> {
    let meshes = r.u64s()?;
    let n = r.len(40)?;
    let mut instances = Vec::with_capacity(n);
    for _ in 0..n {
        instances.push(InstanceHashes {
            identity: r.u64()?,
            geometry: r.u64()?,
            placement: r.u64()?,
            albedo: r.u64()?,
            emission: r.u64()?,
        });
    }
    let ids = r.u64s()?;
    let content = r.u64s()?;
    if ids.len() != content.len() {
        return Err("its light hashes do not pair up".into());
    }
    Ok(SceneHashes {
        meshes,
        instances,
        lights: ids.into_iter().zip(content).collect(),
        sky: r.u64()?,
    })
}

fn write_layout(w: &mut Writer, l: &Layout) {
    w.len(l.meshes.len());
    for m in &l.meshes {
        w.bool(m.is_some());
        let Some(u) = m else { continue };
        w.u32(u.width);
        w.u32(u.height);
        w.f32s(&u.uv1.iter().flat_map(|p| [p.x, p.y]).collect::<Vec<_>>());
        w.bool(u.xref.is_some());
        if let Some(x) = &u.xref {
            w.u32s(x);
        }
        w.u32s(&u.indices);
        w.u32s(&u.triangle_charts);
        w.u32(u.chart_count);
        w.bool(u.origin == UvOrigin::Existing);
        w.f32(u.texels_per_metre);
        w.bool(u.scaled_to_fit);
    }
    w.len(l.instances.len());
    for r in &l.instances {
        w.bool(r.is_some());
        if let Some(r) = r {
            w.u32s(&[r.page, r.x, r.y, r.width, r.height]);
        }
    }
    w.u32s(
        &l.pages
            .iter()
            .flat_map(|p| [p.width, p.height])
            .collect::<Vec<_>>(),
    );
}

fn read_layout(r: &mut Reader<'_>) -> Result<Layout, Bad> {
    let n = r.len(1)?;
    let mut meshes = Vec::with_capacity(n);
    for _ in 0..n {
        if !r.bool()? {
            meshes.push(None);
            continue;
        }
        let (width, height) = (r.u32()?, r.u32()?);
        let uv = r.f32s()?;
        let uv1: Vec<Vec2> = uv.chunks_exact(2).map(|c| Vec2::new(c[0], c[1])).collect();
        let xref = if r.bool()? { Some(r.u32s()?) } else { None };
        let indices = r.u32s()?;
        let triangle_charts = r.u32s()?;
        let chart_count = r.u32()?;
        let origin = if r.bool()? {
            UvOrigin::Existing
        } else {
            UvOrigin::Xatlas
        };
        let texels_per_metre = r.f32()?;
        let scaled_to_fit = r.bool()?;
        let fits = uv.len() % 2 == 0
            && indices.len() % 3 == 0
            && triangle_charts.len() * 3 == indices.len()
            && indices.iter().all(|&i| (i as usize) < uv1.len())
            && xref.as_ref().is_none_or(|x| x.len() == uv1.len());
        if !fits {
            return Err("a mesh's lightmap UVs do not fit its triangles".into());
        }
        meshes.push(Some(MeshUnwrap {
            width,
            height,
            uv1,
            xref,
            indices,
            triangle_charts,
            chart_count,
            origin,
            texels_per_metre,
            scaled_to_fit,
        }));
    }
    let n = r.len(1)?;
    let mut instances = Vec::with_capacity(n);
    for _ in 0..n {
        if !r.bool()? {
            instances.push(None);
            continue;
        }
        let v = r.u32s()?;
        let [page, x, y, width, height] = v[..] else {
            return Err("an instance's rectangle does not read".into());
        };
        instances.push(Some(InstanceRect {
            page,
            x,
            y,
            width,
            height,
        }));
    }
    let p = r.u32s()?;
    if p.len() % 2 != 0 {
        return Err("the page sizes do not pair up".into());
    }
    let pages = p
        .chunks_exact(2)
        .map(|c| PageSize {
            width: c[0],
            height: c[1],
        })
        .collect();
    Ok(Layout {
        meshes,
        instances,
        pages,
        warnings: Vec::new(),
    })
}

/// The cache an earlier bake left in `dir` (`dir/lightbake.cache`), read under the import's
/// rules (a regular file, not followed through a final link, at most `limit` bytes): none
/// when there is no file.
///
/// # Errors
/// Why the file there cannot be used, in one line.
pub fn read_cache(dir: &Path, limit: u64) -> Result<Option<BakeCache>, String> {
    read_cache_file(dir, CACHE_FILE, limit)
}

/// The cache a bake into `dir` that did not finish left there (`dir/lightbake.partial`),
/// under the rules of [`read_cache`].
///
/// # Errors
/// Why the file there cannot be used, in one line.
pub fn read_partial(dir: &Path, limit: u64) -> Result<Option<BakeCache>, String> {
    read_cache_file(dir, PARTIAL_FILE, limit)
}

/// Writes `cache` as `dir/lightbake.partial`: into a new file of a random name in `dir`,
/// then renamed over the old one, so a bake killed while writing leaves the earlier one.
///
/// # Errors
/// The file system's.
pub fn write_partial(dir: &Path, cache: &BakeCache) -> std::io::Result<()> {
    use std::io::Write;
    std::fs::create_dir_all(dir)?;
    let mut file = tempfile::Builder::new()
        .prefix(".lightbake.partial.")
        .tempfile_in(dir)?;
    file.write_all(&cache.to_bytes())?;
    file.persist(dir.join(PARTIAL_FILE))
        .map(drop)
        .map_err(|e| e.error)
}

/// How a bake of `scene` with `settings` resumes the bake that left `partial`: following it,
/// keeping the split stages it finished, when the input and the settings are the same;
/// `None` when they are not (the partial file is then of no use).
pub fn resume(partial: BakeCache, scene: &Scene, settings: &BakeSettings) -> Option<Plan> {
    match edits(&partial, scene, settings) {
        Ok(e) if e.is_empty() => Some(Plan::Edit(Box::new((e, partial)))),
        _ => None,
    }
}

fn read_cache_file(dir: &Path, name: &str, limit: u64) -> Result<Option<BakeCache>, String> {
    let path = dir.join(name);
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(None);
    }
    let bytes = crate::scene::read_regular_file(&path, limit).map_err(|e| e.to_string())?;
    BakeCache::from_bytes(&bytes)
        .map(Some)
        .map_err(|why| format!("{} cannot be used: {why}", path.display()))
}

/// How a bake follows an earlier one.
#[derive(Clone, Debug)]
pub enum Plan {
    /// Every texel is baked; the reason.
    Full(String),
    /// An edit of the cached bake.
    Edit(Box<(Edits, BakeCache)>),
    /// A bake with light groups whose edit only scales each group's light: the weighted sum
    /// of the cached groups' pages.
    Relight(Box<Relighting>),
}

/// A bake relit from the cache ([`relight`]).
#[derive(Clone, Debug)]
pub struct Relighting {
    /// The changes, one line each.
    pub lines: Vec<String>,
    /// Per group of the cache ([`KeptGroups::groups`]), the factor per channel of its light.
    pub weights: Vec<Vec3>,
    /// The cache relit, kept as it is for the next bake (the weights stay relative to it).
    pub cache: BakeCache,
}

/// How a bake of `scene` with `settings` follows the cache `previous` read from its output
/// folder (none, or why it cannot be used); `full` asks for a full bake.
pub fn plan(
    previous: Result<Option<BakeCache>, String>,
    scene: &Scene,
    settings: &BakeSettings,
    full: bool,
) -> Plan {
    match previous {
        _ if full => Plan::Full("a full bake was asked for".into()),
        Ok(None) => Plan::Full("no earlier bake to follow (no cache)".into()),
        Err(why) => Plan::Full(why),
        Ok(Some(cache)) if !settings.groups.is_empty() => match relight(&cache, scene, settings) {
            Ok((lines, weights)) => Plan::Relight(Box::new(Relighting {
                lines,
                weights,
                cache,
            })),
            Err(why) => Plan::Full(why),
        },
        Ok(Some(cache)) => match edits(&cache, scene, settings) {
            Ok(edits) => Plan::Edit(Box::new((edits, cache))),
            Err(why) => Plan::Full(why),
        },
    }
}

impl Plan {
    /// The plan in lines: a full bake's reason, or each change and what it recomputes.
    pub fn describe(&self) -> String {
        match self {
            Plan::Full(why) => format!("incremental: full bake: {why}\n"),
            Plan::Relight(r) => {
                let mut s = String::from(
                    "incremental: relit from the cached bake's light groups (nothing lit)\n",
                );
                for l in &r.lines {
                    s.push_str(&format!("  changed   {l}\n"));
                }
                for (g, w) in r.cache.groups.groups.iter().zip(&r.weights) {
                    if *w != Vec3::ONE {
                        s.push_str(&format!(
                            "  weighted  group {} × ({:.4}, {:.4}, {:.4})\n",
                            g.name, w.x, w.y, w.z
                        ));
                    }
                }
                s
            }
            Plan::Edit(e) if e.0.is_empty() => {
                "incremental: nothing changed since the cached bake: its layout and every value it kept are kept\n".into()
            }
            Plan::Edit(e) => {
                let (edits, cache) = (&e.0, &e.1);
                let mut s = String::from("incremental: an edit of the cached bake\n");
                for l in &edits.lines {
                    s.push_str(&format!("  changed   {l}\n"));
                }
                s.push_str("  layout    kept for every mesh that did not change; changed and added meshes placed in free space\n");
                let changed = edits.changed();
                let (mut kept, mut items, mut again) = (Vec::new(), Vec::new(), Vec::new());
                let mut updated = Vec::new();
                let structure = [Input::Geometry, Input::Layout];
                let moved = structure.iter().any(|i| changed.contains(i));
                for &stage in Stage::ALL.iter().filter(|&&st| runs(st, &cache.settings)) {
                    let name = stage.name();
                    match stage.reads().kept {
                        Kept::Pinned => kept.push(name),
                        Kept::Whole | Kept::Items | Kept::Updated if !stage.changed_by(&changed) => {
                            kept.push(name)
                        }
                        Kept::Items => items.push(name),
                        Kept::Updated if !moved => updated.push(name),
                        Kept::Whole | Kept::Again | Kept::Updated => again.push(name),
                    }
                }
                let mut line = |what: &str, names: &[&str], why: String| {
                    if !names.is_empty() {
                        s.push_str(&format!("  {what:<9} {}: {why}\n", names.join(", ")));
                    }
                };
                line("kept", &kept, "nothing they read changed (the density: the layout stays stable)".into());
                line(
                    "per item",
                    &items,
                    format!(
                        "computed again where the edit can move what a texel or node reads by more than {:.0}% of the bake's estimated error (direct light: where a changed light reaches or a moved box can cast or lift a shadow; gathers: where the coarse light a node gathers moved)",
                        100.0 * SHARE
                    ),
                );
                line(
                    "updated",
                    &updated,
                    "what reads only the geometry and layout kept and the rest brought up to date (the nodes: their basis areas kept, their albedo made again; the coarse level: its cut and matrix kept, its first bounce updated by shooting from the nodes whose reflected direct light changed; the contact fit: its samples kept, its fit made again)".into(),
                );
                line("again", &again, "run again whole (what they read changed, or their output is not kept)".into());
                s
            }
        }
    }
}

/// Whether a bake with `settings` runs `stage` in one process (as far as the settings alone
/// say): the plan's own stages and those of the other methods, solvers or a split bake are
/// left out of an incremental plan's list.
fn runs(stage: Stage, settings: &BakeSettings) -> bool {
    use crate::settings::{Method, SolverChoice};
    let matrix = !matches!(
        settings.radiosity.solver,
        SolverChoice::Auto | SolverChoice::Hierarchical
    );
    match stage {
        Stage::Plan
        | Stage::Indirect
        | Stage::Patches
        | Stage::Calibrate
        | Stage::Relight
        | Stage::Write => false,
        Stage::Vpl => settings.method != Method::Radiosity,
        Stage::Transport | Stage::Solve => matrix,
        Stage::CoarseSolve
        | Stage::GatherPilot
        | Stage::FinalGather
        | Stage::Correction
        | Stage::Reflection => !matrix && settings.method == Method::Radiosity,
        Stage::Nodes | Stage::ErrorEstimate => settings.method == Method::Radiosity,
        Stage::Volume => settings.volume.enabled,
        _ => true,
    }
}

/// The share of the earlier bake's estimated error (relative RMS) that an item's inputs may
/// move by, relative to their earlier value, before it is computed again: items kept within
/// it add at most this share of the error, in quadrature about 12% of it at 0.5.
pub const SHARE: f32 = 0.5;

/// Per split stage of an incremental bake: the items computed again and all items.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StageShare {
    /// The stage.
    pub stage: Stage,
    /// Items computed again.
    pub computed: u64,
    /// Items in all.
    pub items: u64,
}

/// What an incremental bake did, for the report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct IncrementalReport {
    /// Why the bake was full, or none when it followed an edit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub full: Option<String>,
    /// The changes it followed.
    pub changes: Vec<String>,
    /// How the layout was kept.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub layout: Vec<String>,
    /// Each split stage's items computed again.
    pub stages: Vec<StageShare>,
    /// The split stages' items computed again over all items.
    pub recomputed: f64,
}
