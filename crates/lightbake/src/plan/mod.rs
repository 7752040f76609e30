//! The bake plan: before any work, decide which stages the scene needs and say why the others
//! are left out.
//!
//! * no emissive surfaces → no area-light pass;
//! * a mesh that has `TEXCOORD_1` → no unwrap for it (unless `reunwrap`);
//! * a light whose range or cone cannot reach an instance → not evaluated for it; a light that
//!   emits nothing → dropped;
//! * a black sky → no sky rays;
//! * method `direct`, or every albedo zero → no indirect pass;
//! * no lights, no emission and a black sky → nothing to bake: the lightmaps are black and the
//!   raster, ray-tracing and lighting stages are skipped.

use serde::Serialize;

use glam::Vec3;

use crate::lights::LightSource;
use crate::lights::tree::{MANY_LIGHTS, PER_TEXEL_LIGHTS};
use crate::scene::Scene;
use crate::settings::{BakeSettings, Basis, Method, SolverChoice};

mod texel_density;
use texel_density::covered_area;
pub use texel_density::{density_from_budget, density_text, texel_density};

/// One stage of the pipeline and whether it runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedStage {
    /// Stage name as shown in the summary (`unwrap`, `direct`, ...).
    pub name: String,
    /// Whether it runs.
    pub run: bool,
    /// Why it runs or why it is skipped.
    pub reason: String,
}

/// Where one light is evaluated.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LightReach {
    /// Light name.
    pub light: String,
    /// `point`, `spot`, `directional` or `rect`.
    pub kind: &'static str,
    /// Which part of its light the lightmaps hold.
    pub bake: crate::scene::LightBake,
    /// Baked instances the light is evaluated for.
    pub instances: usize,
    /// Baked instances it was skipped for.
    pub skipped: usize,
    /// Why (the reasons met, with up to three instance names each).
    pub skip_reasons: Vec<String>,
}

/// What the bake will do and why.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct BakePlan {
    /// Texel density used, texels per metre.
    pub texel_density: f32,
    /// Where it came from (`settings` or the scene's hint).
    pub texel_density_source: String,
    /// Meshes unwrapped by xatlas.
    pub meshes_to_unwrap: usize,
    /// Meshes keeping their own `TEXCOORD_1`.
    pub meshes_keeping_uv1: usize,
    /// The stages in order.
    pub stages: Vec<PlannedStage>,
    /// Per light.
    pub lights: Vec<LightReach>,
    /// Emissive surfaces exist: the area-light pass runs.
    pub area_lights: bool,
    /// The sky is not black: sky rays are traced.
    pub sky: bool,
    /// No light at all: the lightmaps are black.
    pub nothing_to_bake: bool,
    /// Texels the baked surfaces cover at the density, estimated from their area.
    pub estimated_texels: f64,
    /// Rays the bake is estimated to trace (validity, direct light, sky, the indirect pass,
    /// the volume's probes), an order-of-magnitude figure for refusing what cannot finish.
    pub estimated_rays: f64,
    /// Per instance, the indices of the lights evaluated for it.
    #[serde(skip)]
    lights_per_instance: Vec<Vec<u32>>,
}

impl BakePlan {
    /// Plans a bake of `scene` with `settings`.
    pub fn new(scene: &Scene, settings: &BakeSettings) -> Self {
        let (texel_density, texel_density_source) = texel_density(scene, settings);
        let baked: Vec<usize> = (0..scene.instances.len())
            .filter(|&i| {
                scene.instances[i].bake
                    && scene.meshes[scene.instances[i].mesh].triangle_count() > 0
            })
            .collect();
        let (unwrapping, keeping) = uv_sources(scene, settings, &baked);
        let (lights, lights_per_instance) = light_reaches(scene, &baked);
        let emissive_instances = scene
            .instances
            .iter()
            .filter(|inst| {
                scene.material_of(inst.mesh).is_emissive() && scene.meshes[inst.mesh].area() > 0.0
            })
            .count();
        let any_light = lights.iter().any(|l| l.instances > 0);
        let area_lights = emissive_instances > 0 && !baked.is_empty();
        let sky = scene.sky.max_element() > 0.0 && !baked.is_empty();
        let nothing_to_bake = !(any_light || area_lights || sky) || baked.is_empty();
        let facts = Facts {
            scene,
            settings,
            baked: baked.len(),
            unwrapping,
            keeping,
            lights: lights.iter().filter(|l| l.instances > 0).count(),
            emissive_instances,
            area_lights,
            sky,
            work: !nothing_to_bake,
        };
        let mut stages = facts.geometry_stages();
        let pilot_lights = lights
            .iter()
            .any(|l| l.instances > 0 && l.bake == crate::scene::LightBake::Full);
        stages.insert(1, facts.density_stage(pilot_lights));
        stages.extend(facts.light_stages());
        stages.push(facts.indirect_stage());
        stages.extend(facts.output_stages());
        let estimated_texels = covered_area(scene) * (texel_density as f64).powi(2);
        let estimated_rays =
            estimated_texels * facts.rays_per_texel() + facts.volume_rays(estimated_texels);
        Self {
            estimated_texels,
            estimated_rays,
            texel_density,
            texel_density_source,
            meshes_to_unwrap: unwrapping,
            meshes_keeping_uv1: keeping,
            stages,
            lights,
            area_lights,
            sky,
            nothing_to_bake,
            lights_per_instance,
        }
    }

    /// Refuses a bake estimated to trace more than `settings.max_rays` rays.
    ///
    /// # Errors
    /// [`crate::BakeError::OverRayBudget`] with the estimate and what drives it.
    pub fn check_rays(&self, settings: &BakeSettings) -> crate::Result<()> {
        if self.estimated_rays > settings.max_rays as f64 {
            return Err(crate::BakeError::OverRayBudget {
                estimated: self.estimated_rays,
                budget: settings.max_rays,
                breakdown: format!(
                    "about {:.3e} texels at {} texels/m, {:.0} rays each",
                    self.estimated_texels,
                    density_text(self.texel_density),
                    self.estimated_rays / self.estimated_texels.max(1.0)
                ),
            });
        }
        Ok(())
    }

    /// Indices of the lights to evaluate for instance `i`.
    pub fn lights_for(&self, instance: usize) -> &[u32] {
        &self.lights_per_instance[instance]
    }

    /// Replaces the reason given for a stage (once a decision made later is known).
    pub fn set_reason(&mut self, name: &str, reason: String) {
        if let Some(s) = self.stages.iter_mut().find(|s| s.name == name) {
            s.reason = reason;
        }
    }

    /// Marks the named stage skipped, with the reason (found once the bake knows it).
    pub fn skip(&mut self, name: &str, reason: String) {
        if let Some(s) = self.stages.iter_mut().find(|s| s.name == name) {
            s.run = false;
            s.reason = reason;
        }
    }

    /// Whether the named stage runs.
    pub fn runs(&self, name: &str) -> bool {
        self.stages.iter().any(|s| s.name == name && s.run)
    }

    /// A human-readable plan, one line per stage and per skipped light.
    pub fn describe(&self) -> String {
        let mut s = format!(
            "texel density {} texels/m (from {}); about {:.3e} texels and {:.2e} rays\n",
            density_text(self.texel_density),
            self.texel_density_source,
            self.estimated_texels,
            self.estimated_rays
        );
        if self.nothing_to_bake {
            s.push_str("NOTHING TO BAKE: no light reaches the scene, nothing is emissive and the sky is black; the lightmaps will be black.\n");
        }
        for st in &self.stages {
            s.push_str(&format!(
                "  {:<14} {:<4} {}\n",
                st.name,
                if st.run { "run" } else { "skip" },
                st.reason
            ));
        }
        for l in &self.lights {
            if l.bake == crate::scene::LightBake::IndirectOnly {
                s.push_str(&format!(
                    "  light '{}' ({}) indirect only: its direct light is left to the engine's real-time lighting\n",
                    l.light, l.kind
                ));
            }
            for r in &l.skip_reasons {
                s.push_str(&format!(
                    "  light '{}' ({}) skipped for {r}\n",
                    l.light, l.kind
                ));
            }
        }
        s
    }
}
/// Of the meshes of the baked instances: how many xatlas unwraps and how many keep their own
/// `TEXCOORD_1`.
fn uv_sources(scene: &Scene, settings: &BakeSettings, baked: &[usize]) -> (usize, usize) {
    let mut meshes: Vec<usize> = baked.iter().map(|&i| scene.instances[i].mesh).collect();
    meshes.sort_unstable();
    meshes.dedup();
    let keeping = meshes
        .iter()
        .filter(|&&m| scene.meshes[m].uv1.is_some() && !settings.reunwrap)
        .count();
    (meshes.len() - keeping, keeping)
}

/// Per light, which baked instances it reaches and why it skips the others; per instance,
/// the lights that reach it.
fn light_reaches(scene: &Scene, baked: &[usize]) -> (Vec<LightReach>, Vec<Vec<u32>>) {
    let mut lights_per_instance = vec![Vec::new(); scene.instances.len()];
    let mut lights = Vec::new();
    let bounds: Vec<(Vec3, Vec3)> = baked.iter().map(|&ii| scene.instance_bounds(ii)).collect();
    for (li, light) in scene.lights.iter().enumerate() {
        let mut reach = LightReach {
            light: light.name.clone(),
            kind: light.kind_name(),
            bake: light.bake,
            instances: 0,
            skipped: 0,
            skip_reasons: Vec::new(),
        };
        let mut reasons: Vec<(String, Vec<String>)> = Vec::new();
        for (&ii, &(lo, hi)) in baked.iter().zip(&bounds) {
            match light.misses(lo, hi) {
                Some(why) => {
                    reach.skipped += 1;
                    let who = scene.instances[ii].name.clone();
                    match reasons.iter_mut().find(|(r, _)| r == why) {
                        Some((_, names)) => names.push(who),
                        None => reasons.push((why.to_string(), vec![who])),
                    }
                }
                None => {
                    reach.instances += 1;
                    lights_per_instance[ii].push(li as u32);
                }
            }
        }
        reach.skip_reasons = reasons
            .into_iter()
            .map(|(r, names)| {
                let shown: Vec<&str> = names.iter().take(3).map(String::as_str).collect();
                let more = names.len().saturating_sub(3);
                if more > 0 {
                    format!("{r}: {} and {more} more", shown.join(", "))
                } else {
                    format!("{r}: {}", shown.join(", "))
                }
            })
            .collect();
        lights.push(reach);
    }
    (lights, lights_per_instance)
}

/// What the stage list is decided from.
struct Facts<'a> {
    scene: &'a Scene,
    settings: &'a BakeSettings,
    /// Baked instances.
    baked: usize,
    /// Meshes xatlas unwraps, and meshes that keep their own `TEXCOORD_1`.
    unwrapping: usize,
    keeping: usize,
    /// Lights that reach a baked instance.
    lights: usize,
    emissive_instances: usize,
    area_lights: bool,
    sky: bool,
    /// Something is lit: the lighting stages run.
    work: bool,
}

impl Facts<'_> {
    /// Rays per covered texel, roughly: the validity pass's, direct samples for every light
    /// that reaches a baked instance (emissive surfaces as one more), sky rays, and the
    /// indirect pass's gathers (radiosity's final gather and correction and its coarse
    /// level's share; instant radiosity's shadow rays, about two VPLs per particle).
    fn rays_per_texel(&self) -> f64 {
        let s = self.settings;
        if !self.work {
            return 16.0;
        }
        let weighed = if self.lights > MANY_LIGHTS && self.lights <= PER_TEXEL_LIGHTS {
            // Each texel's shadow rays to every light from two points, once
            // (`direct::light_choice`).
            2.0 * self.lights as f64
        } else {
            0.0
        };
        let lights = if self.lights > MANY_LIGHTS {
            // One picked per sample, and the suns one by one.
            1.0 + self
                .scene
                .lights
                .iter()
                .filter(|l| matches!(l.kind, crate::scene::LightKind::Directional { .. }))
                .count() as f64
        } else {
            self.lights as f64
        } + if self.area_lights { 1.0 } else { 0.0 };
        let direct = s.samples_per_texel as f64 * lights + weighed;
        let sky = if self.sky { s.sky_samples as f64 } else { 0.0 };
        let cluster = (s.cluster_texels as f64).powi(2);
        let indirect = match s.method {
            Method::Direct => 0.0,
            Method::Radiosity => {
                1.5 * s.transport_rays as f64 + 4.0 * s.cluster_rays as f64 / cluster
            }
            Method::Vpl | Method::Hybrid => {
                2.0 * s.vpl_particles as f64
                    + if s.vpl_bias_compensation {
                        s.vpl_compensation_rays as f64
                    } else {
                        0.0
                    }
            }
        };
        16.0 + direct + sky + indirect
    }

    /// The irradiance volume's rays: at most 65 536 probes by default (2²⁰ with an explicit
    /// spacing), each with its rays and a quarter as many emitter samples.
    fn volume_rays(&self, texels: f64) -> f64 {
        let s = self.settings;
        if !(s.irradiance_volume && self.work) {
            return 0.0;
        }
        let probes = match s.probe_spacing {
            None => 65_536f64.min(texels.max(1.0)),
            Some(_) => (1u64 << 20) as f64,
        };
        probes * 1.25 * s.probe_rays as f64
    }
}

fn stage(name: &str, run: bool, reason: String) -> PlannedStage {
    PlannedStage {
        name: name.into(),
        run,
        reason,
    }
}

impl Facts<'_> {
    /// Why the lighting stages are skipped when nothing is lit.
    fn why_not(&self) -> String {
        if self.baked == 0 {
            "no instance is baked".to_string()
        } else {
            "nothing to bake: no light reaches the scene, nothing is emissive and the sky is black"
                .to_string()
        }
    }

    /// `reason` when the lighting stages run, else why they do not.
    fn when_lit(&self, reason: String) -> String {
        if self.work { reason } else { self.why_not() }
    }

    /// Whether the texel density follows the light (see `crate::density`), and why.
    fn density_stage(&self, pilot_lights: bool) -> PlannedStage {
        let s = self.settings;
        let why_not = if !self.work {
            Some(self.why_not())
        } else if !s.adaptive_density {
            Some(
                "turned off (adaptive_density, --uniform-density): every chart at one density"
                    .to_string(),
            )
        } else if s.texel_density.is_some() {
            Some("the settings set the density (texel_density): every chart keeps it".to_string())
        } else if !density_from_budget(self.scene, s) {
            Some(
                "the scene sets its density (extras.lightbake.texel_density): every chart keeps it"
                    .to_string(),
            )
        } else if !pilot_lights {
            Some("no point, spot, directional or rect light has its direct light baked: the pilot sees only those".to_string())
        } else {
            None
        };
        match why_not {
            Some(reason) => stage("density", false, reason),
            None => stage(
                "density",
                true,
                "a pilot of the direct light shares the texel budget out by each chart's error (½ to 2× the density)".to_string(),
            ),
        }
    }

    /// Unwrap, raster, BVH and validity.
    fn geometry_stages(&self) -> Vec<PlannedStage> {
        vec![
            stage(
                "unwrap",
                self.unwrapping > 0 || self.keeping > 0,
                match (self.unwrapping, self.keeping) {
                    (0, 0) => "no instance is baked".to_string(),
                    (u, 0) => format!("xatlas unwraps {u} mesh(es)"),
                    (0, k) => {
                        format!("all {k} mesh(es) keep their own TEXCOORD_1 (validated; no xatlas)")
                    }
                    (u, k) => {
                        format!("xatlas unwraps {u} mesh(es); {k} keep their own TEXCOORD_1")
                    }
                },
            ),
            stage(
                "raster",
                self.work,
                self.when_lit(format!("{} instance(s) into texel patches", self.baked)),
            ),
            stage(
                "bvh",
                self.work,
                self.when_lit(format!(
                    "{} triangles for shadow rays",
                    self.scene.instanced_triangle_count()
                )),
            ),
            stage(
                "validity",
                self.work,
                self.when_lit("move texels out of geometry; mark those that cannot be".into()),
            ),
        ]
    }

    /// Direct lights, area lights and the sky.
    fn light_stages(&self) -> Vec<PlannedStage> {
        let scene = self.scene;
        // Method vpl carries all light, direct included, by VPLs.
        let vpl_only = self.settings.method == Method::Vpl;
        let as_vpls = "method 'vpl': the light sources are the first generation of VPLs";
        vec![
            stage(
                "direct lights",
                self.lights > 0 && self.work && !vpl_only,
                if scene.lights.is_empty() {
                    "the scene has no punctual or directional lights".to_string()
                } else if self.lights == 0 {
                    "no light reaches a baked instance (range, cone or zero intensity)".to_string()
                } else if vpl_only {
                    as_vpls.to_string()
                } else if self.lights > MANY_LIGHTS {
                    format!(
                        "{} of {} light(s) reach baked instances; where more than {MANY_LIGHTS} reach one, each footprint sample takes one light instead of all: picked by the texel's own weights (each light's unoccluded light and its visibility from the texel) up to {PER_TEXEL_LIGHTS} lights, from a light tree (by power over distance²) beyond",
                        self.lights,
                        scene.lights.len()
                    )
                } else {
                    format!(
                        "{} of {} light(s) reach baked instances",
                        self.lights,
                        scene.lights.len()
                    )
                },
            ),
            stage(
                "area lights",
                self.area_lights && self.work && !vpl_only,
                if !self.area_lights {
                    "no emissive surfaces".to_string()
                } else if vpl_only {
                    as_vpls.to_string()
                } else {
                    format!("{} emissive instance(s)", self.emissive_instances)
                },
            ),
            stage(
                "sky",
                self.sky && self.work && !vpl_only,
                if !self.sky {
                    "the sky is black".to_string()
                } else if vpl_only {
                    as_vpls.to_string()
                } else {
                    format!("sky luminance {:?} nits", scene.sky.to_array())
                },
            ),
        ]
    }

    /// Indirect light: radiosity, instant radiosity, or why neither runs.
    fn indirect_stage(&self) -> PlannedStage {
        let (scene, settings) = (self.scene, self.settings);
        let all_black = scene
            .instances
            .iter()
            .all(|inst| scene.material_of(inst.mesh).albedo_factor().max_element() <= 0.0);
        let particles = settings.vpl_time_budget_s.map_or_else(
            || format!("{} particles", settings.vpl_particles),
            |t| format!("particles for a {t} s gather"),
        );
        let (run, why) = match settings.method {
            Method::Direct if all_black => (
                false,
                "method 'direct' computes no interreflection (and every albedo is zero)"
                    .to_string(),
            ),
            Method::Direct => (
                false,
                "method 'direct' computes no interreflection".to_string(),
            ),
            Method::Radiosity | Method::Hybrid if all_black => (
                false,
                "every surface has zero albedo: nothing is reflected".to_string(),
            ),
            _ if !self.work => (false, self.why_not()),
            Method::Radiosity => (
                true,
                format!(
                    "radiosity, {} basis, solver {}{}",
                    match settings.basis {
                        Basis::Linear => "piecewise-linear",
                        Basis::Constant => "piecewise-constant",
                    },
                    settings.solver.name(),
                    if settings.solver == SolverChoice::Auto {
                        " (chosen once the texels are known)"
                    } else {
                        ""
                    }
                ),
            ),
            Method::Hybrid => (
                true,
                format!(
                    "instant radiosity from the first reflection on: {particles}, {:?} walks",
                    settings.vpl_sequence
                ),
            ),
            Method::Vpl => (
                true,
                format!(
                    "instant radiosity, all light from VPLs: {particles}, {:?} walks{}",
                    settings.vpl_sequence,
                    if all_black {
                        " (every albedo is zero: no reflections)"
                    } else {
                        ""
                    }
                ),
            ),
        };
        stage("indirect", run, why)
    }

    /// The texel grid's check (`crate::lightmap::grid_error`): it reads the direct pass's
    /// texels and samples the lights and the sky at points.
    fn grid_error_stage(&self) -> PlannedStage {
        let s = self.settings;
        let why_not = if !self.work {
            Some(self.why_not())
        } else if s.grid_error_points == 0 {
            Some("turned off in the settings (grid_error_points; --grid-error-points 0): the estimate covers sampling noise only".to_string())
        } else if s.method == Method::Vpl {
            Some("method 'vpl' has no direct pass whose texels it could read".to_string())
        } else {
            None
        };
        let run = why_not.is_none();
        stage(
            "grid error",
            run,
            why_not.unwrap_or_else(|| {
                format!(
                    "the direct light between texel centres checked against its value at {} points: the texel grid's own error, added to the estimate",
                    s.grid_error_points
                )
            }),
        )
    }

    /// The finishing steps on the pages, dilation and writing.
    fn output_stages(&self) -> Vec<PlannedStage> {
        let s = self.settings;
        let step = |name: &str, on: bool, off: &str, what: &str| {
            let reason = if !self.work {
                self.when_lit(String::new())
            } else if on {
                what.to_string()
            } else {
                off.to_string()
            };
            stage(name, self.work && on, reason)
        };
        vec![
            step(
                "denoise",
                s.denoise,
                "turned off in the settings (denoise; the preview preset's default is off, medium's and high's on)",
                &format!(
                    "edge-aware filter of {} texels' radius, as strong as each texel's noise warrants",
                    s.denoise_radius
                ),
            ),
            self.grid_error_stage(),
            step(
                "contact fit",
                s.contact_fit,
                "turned off in the settings (contact_fit)",
                "texels next to geometry fitted so the bilinear reconstruction is right on the visible surface",
            ),
            stage(
                "dilate",
                self.work,
                self.when_lit(format!(
                    "fill invalid texels and {} texels of padding",
                    self.settings.padding
                )),
            ),
            step(
                "stitch",
                s.stitch_seams,
                "turned off in the settings (stitch_seams)",
                "both sides of every seam made to agree after bilinear filtering",
            ),
            step(
                "volume",
                s.irradiance_volume,
                "no irradiance volume asked for (irradiance_volume; --irradiance-volume)",
                &format!(
                    "irradiance volume for dynamic objects, {} rays per probe, spacing {}",
                    s.probe_rays,
                    s.probe_spacing.map_or_else(
                        || "from the texel density".to_string(),
                        |d| format!("{d} m")
                    )
                ),
            ),
            stage(
                "write",
                true,
                "lightmaps, baked glTF, manifest and report".to_string(),
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box, plane};
    use crate::scene::{Instance, Light, LightKind};
    use glam::{Affine3A, Vec3};

    #[test]
    fn cornell_area_plan() {
        let s = cornell_box(CornellLight::Area);
        let plan = BakePlan::new(&s, &BakeSettings::default());
        assert!(plan.area_lights && !plan.sky && !plan.nothing_to_bake);
        assert!(!plan.runs("direct lights") && plan.runs("area lights") && !plan.runs("sky"));
        assert_eq!(plan.texel_density, 256.0);
        let text = plan.describe();
        assert!(text.contains("no punctual"), "{text}");
    }

    /// The texel grid's check runs by default, and says why not when its points are 0 or the
    /// method has no direct pass.
    #[test]
    fn grid_error_stage_runs_unless_turned_off_or_without_a_direct_pass() {
        let s = cornell_box(CornellLight::Area);
        assert!(BakePlan::new(&s, &BakeSettings::default()).runs("grid error"));
        let d = BakeSettings::default;
        let off = BakeSettings {
            grid_error_points: 0,
            ..d()
        };
        let vpl = BakeSettings {
            method: Method::Vpl,
            ..d()
        };
        for (settings, why) in [(off, "grid_error_points"), (vpl, "no direct pass")] {
            let plan = BakePlan::new(&s, &settings);
            assert!(!plan.runs("grid error") && plan.describe().contains(why));
        }
    }

    /// An explicit density wins over the scene's hint, which wins over the budget; the budget
    /// spreads its texels over the baked area (density = √(budget / area)).
    #[test]
    fn texel_density_precedence_and_budget() {
        let s = cornell_box(CornellLight::Area);
        let explicit = BakeSettings {
            texel_density: Some(64.0),
            ..BakeSettings::default()
        };
        assert_eq!(texel_density(&s, &explicit).0, 64.0);
        assert_eq!(texel_density(&s, &BakeSettings::default()).0, 256.0);
        let budget = BakeSettings {
            texel_density_from_scene: false,
            texel_budget: 10_000,
            ..BakeSettings::default()
        };
        let (d, why) = texel_density(&s, &budget);
        let area: f32 = (0..s.instances.len()).map(|i| s.instance_area(i)).sum();
        assert!((d * d * area / 10_000.0 - 1.0).abs() < 1e-4, "{d} {area}");
        assert!(why.contains("10000 texels"), "{why}");
    }

    #[test]
    fn unlit_scene_has_nothing_to_bake() {
        let mut s = cornell_box(CornellLight::Point);
        s.lights.clear();
        let plan = BakePlan::new(&s, &BakeSettings::default());
        assert!(plan.nothing_to_bake);
        assert!(!plan.runs("raster") && !plan.runs("direct lights"));
        assert!(plan.describe().contains("NOTHING TO BAKE"));
    }

    #[test]
    fn lights_are_culled_by_range_and_cone() {
        let mut s = Scene::default();
        let m = s.add_mesh(plane("p", 1.0));
        s.instances
            .push(Instance::new("near", m, Affine3A::IDENTITY));
        s.instances.push(Instance::new(
            "far",
            m,
            Affine3A::from_translation(Vec3::new(50.0, 0.0, 0.0)),
        ));
        s.lights.push(Light {
            name: "lamp".into(),
            kind: LightKind::Point,
            color: Vec3::ONE,
            intensity: 10.0,
            range: Some(5.0),
            position: Vec3::new(0.0, 1.0, 0.0),
            direction: Vec3::NEG_Y,
            bake: crate::scene::LightBake::Full,
        });
        s.lights.push(Light {
            name: "spot".into(),
            kind: LightKind::Spot {
                inner_cone_angle: 0.1,
                outer_cone_angle: 0.2,
            },
            color: Vec3::ONE,
            intensity: 10.0,
            range: None,
            position: Vec3::new(50.0, 3.0, 0.0),
            direction: Vec3::NEG_Y,
            bake: crate::scene::LightBake::Full,
        });
        let plan = BakePlan::new(&s, &BakeSettings::default());
        assert_eq!(plan.lights_for(0), &[0]);
        assert_eq!(plan.lights_for(1), &[1]);
        assert_eq!(
            plan.lights[0].skip_reasons,
            vec!["out of range: far".to_string()]
        );
        assert_eq!(
            plan.lights[1].skip_reasons,
            vec!["outside the cone: near".to_string()]
        );
    }
}
