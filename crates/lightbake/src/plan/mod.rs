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
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::stage::Stage;

mod facts;
mod texel_density;
use facts::Facts;
use texel_density::covered_area;
pub use texel_density::{density_text, texel_density};

/// One stage of the pipeline and whether it runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedStage {
    /// The stage.
    pub stage: Stage,
    /// Whether it runs.
    pub run: bool,
    /// Why it runs or why it is skipped.
    pub reason: String,
}

/// What the direct pass samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DirectSource {
    /// Point, spot, directional and rect lights.
    Lights,
    /// Emissive surfaces.
    AreaLights,
    /// The sky.
    Sky,
}

impl DirectSource {
    /// The source's name in the plan.
    pub const fn name(self) -> &'static str {
        match self {
            DirectSource::Lights => "lights",
            DirectSource::AreaLights => "area lights",
            DirectSource::Sky => "sky",
        }
    }
}

/// One source of the direct pass and whether it is sampled.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PlannedSource {
    /// The source.
    pub source: DirectSource,
    /// Whether the direct pass samples it.
    pub used: bool,
    /// Why, or why not.
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
    /// The direct pass's sources.
    pub sources: Vec<PlannedSource>,
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
        let sources = facts.sources();
        stages.push(facts.direct_stage(&sources));
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
            sources,
            lights,
            area_lights,
            sky,
            nothing_to_bake,
            lights_per_instance,
        }
    }

    /// The plan of a bake that follows a cached bake's layout at `density` texels per metre:
    /// that density, and no density pass (the cached charts keep their own).
    pub fn follow_layout(&mut self, density: f32) {
        self.texel_density = density;
        self.texel_density_source = "the cached bake's layout, which this bake follows".into();
        for s in self.stages.iter_mut().filter(|s| s.stage == Stage::Density) {
            s.run = false;
            s.reason = "the cached bake's layout is kept: its charts keep their densities, so no asset that refers to an unchanged mesh changes".into();
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

    /// Whether `stage` runs (for a stage of the indirect pass: whether the indirect pass
    /// runs, see [`Stage::planned_as`]).
    pub fn runs(&self, stage: Stage) -> bool {
        let planned = stage.planned_as();
        self.stages.iter().any(|s| s.stage == planned && s.run)
    }

    /// Whether the direct pass samples `source`.
    pub fn samples(&self, source: DirectSource) -> bool {
        self.sources.iter().any(|s| s.source == source && s.used)
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
                st.stage.name(),
                if st.run { "run" } else { "skip" },
                st.reason
            ));
            if st.stage == Stage::Direct {
                for src in &self.sources {
                    s.push_str(&format!(
                        "    {:<12} {:<4} {}\n",
                        src.source.name(),
                        if src.used { "yes" } else { "no" },
                        src.reason
                    ));
                }
            }
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
        .filter(|&&m| scene.meshes[m].uv1.is_some() && !settings.layout.reunwrap)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box, plane};
    use crate::scene::{Instance, Light, LightKind};
    use crate::settings::Method;
    use glam::{Affine3A, Vec3};

    #[test]
    fn cornell_area_plan() {
        let s = cornell_box(CornellLight::Area);
        let plan = BakePlan::new(&s, &BakeSettings::default());
        assert!(plan.area_lights && !plan.sky && !plan.nothing_to_bake);
        assert!(!plan.samples(DirectSource::Lights) && plan.samples(DirectSource::AreaLights));
        assert!(!plan.samples(DirectSource::Sky) && plan.runs(Stage::Direct));
        assert_eq!(plan.texel_density, 256.0);
        let text = plan.describe();
        assert!(text.contains("no punctual"), "{text}");
    }

    /// The texel grid's check runs by default, and says why not when its points are 0 or the
    /// method has no direct pass.
    #[test]
    fn grid_error_stage_runs_unless_turned_off_or_without_a_direct_pass() {
        let s = cornell_box(CornellLight::Area);
        assert!(BakePlan::new(&s, &BakeSettings::default()).runs(Stage::GridError));
        let d = BakeSettings::default;
        let off = {
            let mut s = d();
            s.checks.grid_error_points = 0;
            s
        };
        let vpl = BakeSettings {
            method: Method::Vpl,
            ..d()
        };
        for (settings, why) in [(off, "grid_error_points"), (vpl, "no direct pass")] {
            let plan = BakePlan::new(&s, &settings);
            assert!(!plan.runs(Stage::GridError) && plan.describe().contains(why));
        }
    }

    /// An explicit density wins over the scene's hint, which wins over the budget; the budget
    /// spreads its texels over the baked area (density = √(budget / area)).
    #[test]
    fn texel_density_precedence_and_budget() {
        let s = cornell_box(CornellLight::Area);
        let explicit = {
            let mut s = BakeSettings::default();
            s.layout.texel_density = Some(64.0);
            s
        };
        assert_eq!(texel_density(&s, &explicit).0, 64.0);
        assert_eq!(texel_density(&s, &BakeSettings::default()).0, 256.0);
        let budget = {
            let mut s = BakeSettings::default();
            s.layout.texel_density_from_scene = false;
            s.layout.texel_budget = 10_000;
            s
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
        assert!(!plan.runs(Stage::Raster) && !plan.runs(Stage::Direct));
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
