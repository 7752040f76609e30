//! Which stages a scene needs and why: the facts the plan is decided from, the stage list
//! and the rough ray count the plan refuses over-budget bakes by.

use super::texel_density::density_from_budget;
use super::{DirectSource, PlannedSource, PlannedStage};
use crate::lights::tree::{MANY_LIGHTS, PER_TEXEL_LIGHTS, PICKS_PER_SAMPLE};
use crate::scene::Scene;
use crate::settings::{BakeSettings, Basis, Method, SolverChoice};
use crate::stage::Stage;

/// What the stage list is decided from.
pub(super) struct Facts<'a> {
    pub(super) scene: &'a Scene,
    pub(super) settings: &'a BakeSettings,
    /// Baked instances.
    pub(super) baked: usize,
    /// Meshes xatlas unwraps, and meshes that keep their own `TEXCOORD_1`.
    pub(super) unwrapping: usize,
    pub(super) keeping: usize,
    /// Lights that reach a baked instance.
    pub(super) lights: usize,
    pub(super) emissive_instances: usize,
    pub(super) area_lights: bool,
    pub(super) sky: bool,
    /// Something is lit: the lighting stages run.
    pub(super) work: bool,
}

impl Facts<'_> {
    /// Rays per covered texel, roughly: the validity pass's, direct samples for every light
    /// that reaches a baked instance (emissive surfaces as one more), sky rays, and the
    /// indirect pass's gathers (radiosity's final gather and correction and its coarse
    /// level's share; instant radiosity's shadow rays, about two VPLs per particle).
    pub(super) fn rays_per_texel(&self) -> f64 {
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
            // Picked per sample (four by the texel's weights, one from the tree), and the
            // suns one by one.
            let picks = if self.lights <= PER_TEXEL_LIGHTS {
                PICKS_PER_SAMPLE as f64
            } else {
                1.0
            };
            picks
                + self
                    .scene
                    .lights
                    .iter()
                    .filter(|l| matches!(l.kind, crate::scene::LightKind::Directional { .. }))
                    .count() as f64
        } else {
            self.lights as f64
        } + if self.area_lights { 1.0 } else { 0.0 };
        let direct = s.direct.samples_per_texel as f64 * lights + weighed;
        let sky = if self.sky {
            s.direct.sky_samples as f64
        } else {
            0.0
        };
        let cluster = (s.radiosity.cluster_texels as f64).powi(2);
        let indirect = match s.method {
            Method::Direct => 0.0,
            Method::Radiosity => {
                1.5 * s.radiosity.transport_rays as f64
                    + 4.0 * s.radiosity.cluster_rays as f64 / cluster
            }
            Method::Vpl | Method::Hybrid => {
                // Through cuts a texel traces one ray per node of its cut; Keller's gather
                // one per VPL (about two per particle).
                let gather = if s.vpl.cut_size > 0 {
                    s.vpl.cut_size as f64 + self.lights as f64
                } else {
                    2.0 * s.vpl.particles as f64
                };
                gather
                    + if s.vpl.bias_compensation {
                        s.vpl.compensation_rays as f64
                    } else {
                        0.0
                    }
            }
        };
        16.0 + direct + sky + indirect
    }

    /// The irradiance volumes' rays: at most 65 536 probes per volume by default (2²⁰ with an
    /// explicit spacing), each with its rays and a quarter as many emitter samples.
    pub(super) fn volume_rays(&self, texels: f64) -> f64 {
        let s = self.settings;
        if !(s.volume.enabled && self.work) {
            return 0.0;
        }
        let volumes = s.volume.regions.max(1) as f64;
        let probes = match s.volume.probe_spacing {
            None => (65_536.0 * volumes).min(texels.max(1.0)),
            Some(_) => (1u64 << 20) as f64 * volumes,
        };
        probes * 1.25 * s.volume.probe_rays as f64
    }
}

fn source(source: DirectSource, used: bool, reason: String) -> PlannedSource {
    PlannedSource {
        source,
        used,
        reason,
    }
}

fn stage(stage: Stage, run: bool, reason: String) -> PlannedStage {
    PlannedStage { stage, run, reason }
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
    pub(super) fn density_stage(&self, pilot_lights: bool) -> PlannedStage {
        let s = self.settings;
        let why_not = if !self.work {
            Some(self.why_not())
        } else if !s.layout.adaptive_density {
            Some(
                "turned off (layout.adaptive_density, --uniform-density): every chart at one density"
                    .to_string(),
            )
        } else if s.layout.texel_density.is_some() {
            Some(
                "the settings set the density (layout.texel_density): every chart keeps it"
                    .to_string(),
            )
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
            Some(reason) => stage(Stage::Density, false, reason),
            None => stage(
                Stage::Density,
                true,
                "a pilot of the direct light shares the texel budget out by each chart's error (½ to 2× the density)".to_string(),
            ),
        }
    }

    /// Unwrap, raster, BVH and validity.
    pub(super) fn geometry_stages(&self) -> Vec<PlannedStage> {
        vec![
            stage(Stage::Unwrap, self.unwrapping > 0 || self.keeping > 0, {
                let moved = match self.settings.formats.ktx2_bc6h {
                    true => ", their charts moved by whole texels onto BC6H blocks",
                    false => "",
                };
                match (self.unwrapping, self.keeping) {
                    (0, 0) => "no instance is baked".to_string(),
                    (u, 0) => format!("xatlas unwraps {u} mesh(es)"),
                    (0, k) => format!(
                        "all {k} mesh(es) keep their own TEXCOORD_1 (validated; no xatlas{moved})"
                    ),
                    (u, k) => {
                        format!("xatlas unwraps {u} mesh(es); {k} keep their own TEXCOORD_1{moved}")
                    }
                }
            }),
            stage(
                Stage::Raster,
                self.work,
                self.when_lit(format!("{} instance(s) into texel patches", self.baked)),
            ),
            stage(
                Stage::Bvh,
                self.work,
                self.when_lit(format!(
                    "{} triangles for shadow rays",
                    self.scene.instanced_triangle_count()
                )),
            ),
            stage(
                Stage::Validity,
                self.work,
                self.when_lit("move texels out of geometry; mark those that cannot be".into()),
            ),
        ]
    }

    /// The direct pass: it runs whenever something is lit, except with method `vpl` (whose
    /// VPLs carry the direct light too).
    pub(super) fn direct_stage(&self, sources: &[PlannedSource]) -> PlannedStage {
        let used: Vec<&str> = sources
            .iter()
            .filter(|s| s.used)
            .map(|s| s.source.name())
            .collect();
        let run = self.work && self.settings.method != Method::Vpl;
        let reason = if !self.work {
            self.why_not()
        } else if !run {
            "method 'vpl': the light sources are the first generation of VPLs".to_string()
        } else {
            format!("shadow rays to: {}", used.join(", "))
        };
        stage(Stage::Direct, run, reason)
    }

    /// Direct lights, area lights and the sky.
    pub(super) fn sources(&self) -> Vec<PlannedSource> {
        let scene = self.scene;
        // Method vpl carries all light, direct included, by VPLs.
        let vpl_only = self.settings.method == Method::Vpl;
        let as_vpls = "method 'vpl': the light sources are the first generation of VPLs";
        vec![
            source(
                DirectSource::Lights,
                self.lights > 0 && self.work && !vpl_only,
                if scene.lights.is_empty() {
                    "the scene has no punctual or directional lights".to_string()
                } else if self.lights == 0 {
                    "no light reaches a baked instance (range, cone or zero intensity)".to_string()
                } else if vpl_only {
                    as_vpls.to_string()
                } else if self.lights > MANY_LIGHTS {
                    format!(
                        "{} of {} light(s) reach baked instances; where more than {MANY_LIGHTS} reach one, each footprint sample takes some lights instead of all: {PICKS_PER_SAMPLE} picked by the texel's own weights (each light's unoccluded light and its visibility from the texel) up to {PER_TEXEL_LIGHTS} lights, one from a light tree (by power over distance²) beyond",
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
            source(
                DirectSource::AreaLights,
                self.area_lights && self.work && !vpl_only,
                if !self.area_lights {
                    "no emissive surfaces".to_string()
                } else if vpl_only {
                    as_vpls.to_string()
                } else {
                    format!("{} emissive instance(s)", self.emissive_instances)
                },
            ),
            source(
                DirectSource::Sky,
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
    pub(super) fn indirect_stage(&self) -> PlannedStage {
        let (scene, settings) = (self.scene, self.settings);
        let all_black = scene
            .instances
            .iter()
            .all(|inst| scene.material_of(inst.mesh).albedo_factor().max_element() <= 0.0);
        let particles = settings.vpl.time_budget_s.map_or_else(
            || format!("{} particles", settings.vpl.particles),
            |t| format!("particles for a {t} s gather"),
        ) + &match settings.vpl.cut_size {
            0 => ", every VPL gathered at every texel".to_string(),
            c => format!(", gathered through lightcuts of {c} nodes"),
        };
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
                    match settings.radiosity.basis {
                        Basis::Linear => "piecewise-linear",
                        Basis::Constant => "piecewise-constant",
                    },
                    settings.radiosity.solver.name(),
                    if settings.radiosity.solver == SolverChoice::Auto {
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
                    settings.vpl.sequence
                ),
            ),
            Method::Vpl => (
                true,
                format!(
                    "instant radiosity, all light from VPLs: {particles}, {:?} walks{}",
                    settings.vpl.sequence,
                    if all_black {
                        " (every albedo is zero: no reflections)"
                    } else {
                        ""
                    }
                ),
            ),
        };
        stage(Stage::Indirect, run, why)
    }

    /// The texel grid's check (`crate::lightmap::grid_error`): it reads the direct pass's
    /// texels and samples the lights and the sky at points.
    fn grid_error_stage(&self) -> PlannedStage {
        let s = self.settings;
        let why_not = if !self.work {
            Some(self.why_not())
        } else if s.checks.grid_error_points == 0 {
            Some("turned off in the settings (checks.grid_error_points; --grid-error-points 0): the estimate covers sampling noise only".to_string())
        } else if s.method == Method::Vpl {
            Some("method 'vpl' has no direct pass whose texels it could read".to_string())
        } else {
            None
        };
        let run = why_not.is_none();
        stage(
            Stage::GridError,
            run,
            why_not.unwrap_or_else(|| {
                format!(
                    "the direct light between texel centres checked against its value at {} points: the texel grid's own error, added to the estimate",
                    s.checks.grid_error_points
                )
            }),
        )
    }

    /// The finishing steps on the pages, dilation and writing.
    pub(super) fn output_stages(&self) -> Vec<PlannedStage> {
        let s = self.settings;
        let step = |name: Stage, on: bool, off: &str, what: &str| {
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
                Stage::Denoise,
                s.finish.denoise,
                "turned off in the settings (finish.denoise; the preview preset's default is off, medium's and high's on)",
                &format!(
                    "edge-aware filter of {} texels' radius, as strong as each texel's noise warrants",
                    s.finish.denoise_radius
                ),
            ),
            self.grid_error_stage(),
            step(
                Stage::ContactFit,
                s.finish.contact_fit,
                "turned off in the settings (finish.contact_fit)",
                "texels next to geometry fitted so the bilinear reconstruction is right on the visible surface",
            ),
            stage(
                Stage::Dilate,
                self.work,
                self.when_lit(format!(
                    "fill invalid texels and {} texels of padding",
                    self.settings.layout.padding
                )),
            ),
            step(
                Stage::Stitch,
                s.finish.stitch_seams,
                "turned off in the settings (finish.stitch_seams)",
                "both sides of every seam made to agree after bilinear filtering",
            ),
            step(
                Stage::Volume,
                s.volume.enabled,
                "no irradiance volume asked for (volume.enabled; --irradiance-volume)",
                &format!(
                    "irradiance volume for dynamic objects, {} rays per probe, spacing {}",
                    s.volume.probe_rays,
                    s.volume.probe_spacing.map_or_else(
                        || "from the texel density and the level's headroom".to_string(),
                        |d| format!("{d} m")
                    )
                ),
            ),
            stage(
                Stage::Write,
                true,
                "lightmaps, baked glTF, manifest and report".to_string(),
            ),
        ]
    }
}
