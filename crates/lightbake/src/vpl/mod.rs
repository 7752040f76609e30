//! Instant radiosity (Keller 1997, "Instant Radiosity", SIGGRAPH 97): light is carried by
//! virtual point lights left at the vertices of quasi-random walks from the light sources
//! ([`walk`]), then gathered into every texel with shadow rays ([`gather`]): by default
//! through lightcuts ([`cut`]: one VPL per node of a cut of a tree over them, so a texel
//! traces `vpl.cut_size` rays however many VPLs there are), or every VPL at every texel
//! (`vpl.cut_size` 0, Keller's own gather).
//!
//! Measured with `bake --verify 1024` at the medium preset: the Cornell box 18.4% → 3.5% and
//! the sunlit room 6.1% → 2.9% from the path tracer, in 5.9 → 2.1 s and 4.3 → 3.6 s, against
//! Keller's gather of 1 024 particles (docs/benchmarks.md, "Instant radiosity").
//!
//! Two methods use it:
//!
//! * `vpl`: all light comes from VPLs; the light sources themselves are the first generation
//!   (punctual lights exactly, emitters and the sun and sky as samples);
//! * `hybrid`: direct light is computed exactly by [`crate::direct`]; VPLs from the first
//!   reflection on carry the indirect light.
//!
//! The number of particles is set directly (`vpl.particles`) or from a time budget
//! (`vpl.time_budget_s`, measured against a pilot of shadow rays).

pub mod compensation;
pub mod cut;
pub mod gather;
pub mod walk;

use std::time::Instant;

use glam::Vec3;
use serde::Serialize;

use crate::color::luminance;
use crate::context::BakeContext;
use crate::error_estimate::{ErrorEstimate, rms_luminance};
use crate::lights::Emitters;
use crate::progress::Progress;
use crate::sampling::Sequence;
pub use walk::WalkSettings;

/// Counters of the instant-radiosity pass, for the report.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct VplReport {
    /// Particles started (N).
    pub particles: u32,
    /// How N was chosen.
    pub particles_reason: String,
    /// Number pattern.
    pub sequence: Sequence,
    /// VPLs made.
    pub vpls: usize,
    /// VPLs per path depth.
    pub per_depth: Vec<u32>,
    /// Keller's ρ̄.
    pub mean_reflectivity: f32,
    /// The clamp distance d_c (m); G is clamped at 1/d_c².
    pub clamp_distance: f32,
    /// Share of the gathered VPL light the clamp removed (before any compensation).
    pub clamped_fraction: f64,
    /// Whether bias compensation ran.
    pub compensated: bool,
    /// Nodes per cut of the gather (0: every VPL at every texel; `vpl::cut`).
    pub cut_size: u32,
    /// Fixed-point iterations of the compensation (0 when it did not run; see
    /// `vpl::compensation`).
    pub compensation_iterations: u32,
    /// Why the compensation was cut short, when it was (a warning for the report).
    pub compensation_note: Option<String>,
    /// Shadow rays of the gather.
    pub shadow_rays: u64,
    /// VPL–texel pairs culled before tracing.
    pub culled: u64,
    /// Gather wall time, s.
    pub gather_seconds: f64,
    /// Shadow rays per second in the gather.
    pub shadow_rays_per_second: f64,
    /// The gather's own error estimate (variance over the particle paths; see
    /// [`crate::error_estimate`]), relative to the direct plus VPL light of the valid texels.
    pub error: ErrorEstimate,
}

impl VplReport {
    /// One line for a terminal: particles, VPLs, the gather's shadow rays and the clamp.
    pub fn summary(&self) -> String {
        format!(
            "instant radiosity: {} particles ({}), {} VPLs, {} shadow rays in {:.2} s ({:.2} Mrays/s), {:.1}% of the VPL light clamped{}",
            self.particles,
            self.particles_reason,
            self.vpls,
            self.shadow_rays,
            self.gather_seconds,
            self.shadow_rays_per_second / 1e6,
            100.0 * self.clamped_fraction,
            if self.compensated {
                " and restored"
            } else {
                ""
            }
        )
    }
}

/// The clamp distance for a scene: the setting, or 2% of the scene's diagonal.
pub fn clamp_distance(ctx: &BakeContext<'_>) -> f32 {
    ctx.settings
        .vpl
        .clamp_distance
        .unwrap_or(0.02 * ctx.rays.extent)
        .max(1e-9)
}

/// The VPLs Keller's walk leaves for the settings' particles (an upper estimate for the
/// memory plan): N·Σ ρ̄ᵏ over the reflections followed, ρ̄ the area-weighted mean albedo of
/// the scene's instances (as [`walk::mean_reflectivity`] weighs it), plus the punctual lights.
pub fn expected_vpls(scene: &crate::scene::Scene, s: &crate::settings::BakeSettings) -> u64 {
    let of_instance = walk::instance_reflectivity(scene);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for i in 0..scene.instances.len() {
        let area = scene.instance_area(i) as f64;
        num += of_instance(i) * area;
        den += area;
    }
    let rho = if den > 0.0 {
        (num / den).clamp(0.0, 0.99)
    } else {
        0.0
    };
    let depth = s.vpl.max_depth.min(walk::MAX_DEPTH) as i32;
    let per_particle: f64 = (0..=depth).map(|k| rho.powi(k)).sum();
    (s.vpl.particles as f64 * per_particle).ceil() as u64 + scene.lights.len() as u64
}

/// Chooses N and the cut: the settings, or what fits the time budget at the measured
/// shadow-ray rate. Through cuts the budget sets the cut alone (a texel's rays), and N stays
/// as set, so the memory the plan admitted for the VPLs holds.
fn particle_count(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    first_generation: bool,
) -> (u32, u32, String) {
    let s = ctx.settings;
    let Some(budget) = s.vpl.time_budget_s else {
        return (
            s.vpl.particles,
            s.vpl.cut_size,
            "set in the settings".into(),
        );
    };
    // Pilot: a small walk and a gather over a sample of texels.
    let pilot = walk::walk(
        ctx.scene,
        ctx.rays,
        emitters,
        &WalkSettings {
            particles: 64,
            sequence: s.vpl.sequence,
            seed: s.seed,
            max_depth: s.vpl.max_depth,
            first_generation,
        },
    );
    let patches = &ctx.patches.patches;
    let step = (patches.len() / 256).max(1);
    let sample: Vec<crate::raster::Patch> = patches.iter().step_by(step).copied().collect();
    let sub = crate::raster::Patches {
        patches: sample,
        ..crate::raster::Patches::default()
    };
    let sub_ctx = BakeContext {
        patches: &sub,
        ..*ctx
    };
    let start = Instant::now();
    let g = gather::gather(
        &sub_ctx,
        &pilot.vpls,
        pilot.particles,
        1e30,
        &Progress::new(),
    );
    let seconds = start.elapsed().as_secs_f64().max(1e-6);
    if s.vpl.cut_size > 0 {
        // Through cuts a texel costs a ray per node of its cut however many VPLs there are.
        let per_ray = seconds / g.shadow_rays.max(1) as f64;
        let cut = (budget / (per_ray * patches.len().max(1) as f64)).floor();
        let cut = cut.clamp(16.0, crate::settings::vpl::MAX_CUT as f64) as u32;
        return (
            s.vpl.particles,
            cut,
            format!(
                "set in the settings; time budget {budget} s at {:.1} ns per shadow ray of Keller's gather: cuts of {cut} nodes",
                per_ray * 1e9
            ),
        );
    }
    let pairs = (sub.patches.len() * pilot.vpls.len().max(1)) as f64;
    let seconds_per_pair = seconds / pairs;
    let vpls_per_particle = pilot.vpls.len().max(1) as f64 / 64.0;
    let n = (budget / (seconds_per_pair * patches.len().max(1) as f64 * vpls_per_particle)).floor();
    let n = n.clamp(16.0, 1e7) as u32;
    (
        n,
        0,
        format!(
            "time budget {budget} s at {:.2} µs per VPL–texel pair ({} shadow rays in the pilot)",
            seconds_per_pair * 1e6,
            g.shadow_rays
        ),
    )
}

/// What instant radiosity gives the bake.
#[derive(Clone, Debug)]
pub struct FromVpls {
    /// Irradiance per patch from the VPLs, lux, linear RGB.
    pub irradiance: Vec<Vec3>,
    /// The report.
    pub report: VplReport,
    /// Rays traced.
    pub rays: u64,
}

/// Runs the walk, the gather and (optionally) the compensation. `first_generation`: method
/// `vpl` (true) or `hybrid` (false). `direct`: per-patch direct irradiance already computed
/// (hybrid), used as the exitance source of the compensation.
pub fn instant_radiosity(
    ctx: &BakeContext<'_>,
    emitters: &Emitters,
    first_generation: bool,
    direct: Option<&[Vec3]>,
    progress: &Progress,
) -> FromVpls {
    let s = ctx.settings;
    let (particles, cut_size, reason) = particle_count(ctx, emitters, first_generation);
    let set = walk::walk(
        ctx.scene,
        ctx.rays,
        emitters,
        &WalkSettings {
            particles,
            sequence: s.vpl.sequence,
            seed: s.seed,
            max_depth: s.vpl.max_depth,
            first_generation,
        },
    );
    let d_c = clamp_distance(ctx);
    let bound = 1.0 / (d_c * d_c);
    let start = Instant::now();
    let gathered = if cut_size > 0 {
        gather::gather_cut(
            ctx,
            &set.vpls,
            set.particles,
            bound,
            cut_size as usize,
            s.seed,
            progress,
        )
    } else {
        gather::gather(ctx, &set.vpls, set.particles, bound, progress)
    };
    let gather_seconds = start.elapsed().as_secs_f64();
    let weigh = |v: &[Vec3]| -> f64 {
        v.iter()
            .zip(&ctx.patches.patches)
            .map(|(e, p)| luminance(*e) as f64 * p.area as f64)
            .sum()
    };
    let total = weigh(&gathered.irradiance) + weigh(&gathered.clamped);
    let mut irradiance = gathered.irradiance;
    let mut rays = set.rays + gathered.shadow_rays;
    let compensated = s.vpl.bias_compensation;
    let mut compensation_iterations = 0u32;
    let mut compensation_note = None;
    if compensated {
        let c =
            compensation::compensate(ctx, &irradiance, direct, first_generation, bound, progress);
        rays += c.rays;
        compensation_iterations = c.iterations;
        compensation_note = c.note;
        for (e, x) in irradiance.iter_mut().zip(c.irradiance) {
            *e += x;
        }
    }
    let report = VplReport {
        particles,
        particles_reason: reason,
        sequence: s.vpl.sequence,
        vpls: set.vpls.len(),
        per_depth: set.per_depth.clone(),
        mean_reflectivity: set.mean_reflectivity,
        clamp_distance: d_c,
        clamped_fraction: if total > 0.0 {
            weigh(&gathered.clamped) / total
        } else {
            0.0
        },
        compensated,
        compensation_iterations,
        compensation_note,
        shadow_rays: gathered.shadow_rays,
        culled: gathered.culled,
        gather_seconds,
        shadow_rays_per_second: gathered.shadow_rays as f64 / gather_seconds.max(1e-9),
        cut_size,
        error: {
            let valid = |i: usize| ctx.patches.patches[i].is_valid();
            let se: Vec<f32> = (0..irradiance.len())
                .filter(|&i| valid(i))
                .map(|i| gathered.standard_error[i])
                .collect();
            let total: Vec<Vec3> = (0..irradiance.len())
                .filter(|&i| valid(i))
                .map(|i| irradiance[i] + direct.map_or(Vec3::ZERO, |d| d[i]))
                .collect();
            let method = if cut_size > 0 {
                format!(
                    "variance over the picks of cuts of {cut_size} nodes (adjacent nodes paired) and over {particles} particle paths"
                )
            } else {
                format!("variance over {particles} particle paths")
            };
            ErrorEstimate::from_standard_errors(&se, rms_luminance(&total), method)
        },
    };
    FromVpls {
        irradiance,
        report,
        rays,
    }
}
