//! Particles from the lights and Keller's quasi-random walk (Keller 1997, "Instant
//! Radiosity", §3, the algorithm of figure 2).
//!
//! N particles leave the light sources, each light chosen in proportion to its power. With the
//! mean reflectivity ρ̄ = Σ ρ_k·A_k / Σ A_k, particle i (of N) makes k reflections where
//! ⌊N·ρ̄^(k+1)⌋ ≤ i < ⌊N·ρ̄^k⌋: so ⌊N·ρ̄^j⌋ particles reach generation j, and the number of
//! path vertices — virtual point lights — stays below N/(1 − ρ̄). Instead of absorbing
//! particles at random, the survivors carry the power of the absorbed ones: at every
//! reflection the power is multiplied by ρ(y)/ρ̄.
//!
//! Every random decision of particle i is dimension d of point i of a [`Sequence`] (Halton by
//! default): 0 picks the light, 1–2 the point on it, 3–4 the direction it leaves in, and
//! 5 + 2j, 6 + 2j the cosine-distributed direction of reflection j.

use glam::{Vec2, Vec3};

use crate::bvh::{Hit, RayScene};
use crate::color::luminance;
use crate::lights::{Emission, Emitters, LightSource, SceneDisc, Start, sky};
use crate::sampling::{Sequence, cosine_hemisphere};
use crate::scene::Scene;
pub use crate::settings::MAX_VPL_DEPTH as MAX_DEPTH;

/// What kind of light a VPL is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum VplKind {
    /// A point of a surface sending `power` diffusely (cosine lobe) about `normal`: a
    /// reflection, or a sample of an emissive triangle. Irradiance at x:
    /// E = Φ/π · cosθ_y·cosθ_x / r².
    Diffuse {
        /// Unit normal of the surface at the VPL.
        normal: Vec3,
    },
    /// A punctual light of the scene itself (index into [`Scene::lights`]), evaluated exactly.
    Punctual {
        /// Light index.
        light: u32,
    },
    /// Parallel light travelling along `direction` with irradiance `irradiance` (lux) on a
    /// surface facing it: a sample of the sun or of the sky.
    Directional {
        /// Unit direction the light travels.
        direction: Vec3,
        /// Irradiance on a surface facing the light, lux, linear RGB.
        irradiance: Vec3,
    },
}

/// A virtual point light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Vpl {
    /// World position, m (for directional VPLs: unused).
    pub position: Vec3,
    /// Power it sends, lumens, linear RGB (diffuse VPLs).
    pub power: Vec3,
    /// Kind and shape.
    pub kind: VplKind,
    /// Path depth: 0 on a light, j after j reflections.
    pub depth: u32,
    /// The particle whose path made it ([`Vpl::EXACT`] for the punctual lights themselves,
    /// which are not samples). The VPLs of one path are stored together, in path order.
    pub path: u32,
}

impl Vpl {
    /// [`Vpl::path`] of a VPL that is not a sample (a punctual light as the first generation).
    pub const EXACT: u32 = u32::MAX;
}

/// The VPLs of one bake and how they came about.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VplSet {
    /// The VPLs.
    pub vpls: Vec<Vpl>,
    /// Particles started.
    pub particles: u32,
    /// Keller's mean reflectivity ρ̄ (luminance of the albedo, area-weighted).
    pub mean_reflectivity: f32,
    /// VPLs per depth.
    pub per_depth: Vec<u32>,
    /// Rays traced by the walk.
    pub rays: u64,
}

/// One emitting thing the particles start from, with its power (lumens, RGB).
#[derive(Clone, Copy, Debug)]
enum Source {
    Light(u32),
    Emitters,
    Sky,
}

/// Albedo of the surface at a hit ([`crate::scene::Material::diffuse_albedo`]).
pub fn albedo_at(scene: &Scene, rays: &RayScene, hit: &Hit) -> Vec3 {
    let info = rays.triangles[hit.triangle as usize];
    scene.albedo_at(
        info.instance as usize,
        info.local as usize,
        Vec2::new(hit.u, hit.v),
    )
}

/// Keller's ρ̄: the area-weighted mean of the albedo's luminance over every triangle (each
/// material's albedo averaged over its texture).
pub fn mean_reflectivity(scene: &Scene, rays: &RayScene) -> f32 {
    let of_instance = instance_reflectivity(scene);
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for info in &rays.triangles {
        num += of_instance(info.instance as usize) * info.area as f64;
        den += info.area as f64;
    }
    if den > 0.0 { (num / den) as f32 } else { 0.0 }
}

/// The luminance of each instance's mean diffuse albedo, by instance index: each material's
/// mean taken once (a textured material's mean reads its whole texture); meshes without a
/// material take the default one.
pub fn instance_reflectivity(scene: &Scene) -> impl Fn(usize) -> f64 + '_ {
    let of_material =
        |m: &crate::scene::Material| luminance(m.mean_diffuse_albedo(&scene.textures)) as f64;
    let materials: Vec<f64> = scene.materials.iter().map(of_material).collect();
    let default = of_material(&crate::scene::Material::default());
    move |instance| {
        let mesh = scene.instances[instance].mesh;
        scene.meshes[mesh]
            .material
            .map_or(default, |i| materials[i])
    }
}

/// What drives the walk.
#[derive(Clone, Copy, Debug)]
pub struct WalkSettings {
    /// Particles to start (N).
    pub particles: u32,
    /// Number pattern.
    pub sequence: Sequence,
    /// Seed (for the scrambled, jittered and random patterns).
    pub seed: u32,
    /// Deepest reflection followed (at most [`MAX_DEPTH`]).
    pub max_depth: u32,
    /// Keep depth-0 VPLs (method `vpl`); drop them when direct light is computed exactly
    /// (method `hybrid`).
    pub first_generation: bool,
}

/// Starts the particles and walks them through the scene.
pub fn walk(
    scene: &Scene,
    rays: &RayScene,
    emitters: &Emitters,
    settings: &WalkSettings,
) -> VplSet {
    let n = settings.particles.max(1);
    let seq = settings.sequence;
    let sample = |i: u32, dim: usize| seq.sample(i, n, dim, settings.seed);
    let disc = SceneDisc::covering(rays);

    // Sources and their power (lumens, RGB).
    let mut sources: Vec<(Source, Vec3)> = Vec::new();
    for (li, l) in scene.lights.iter().enumerate() {
        let power = l.power(&disc);
        if luminance(power) > 0.0 {
            sources.push((Source::Light(li as u32), power));
        }
    }
    if !emitters.is_empty() {
        sources.push((Source::Emitters, emitters.power()));
    }
    if scene.sky.max_element() > 0.0 {
        sources.push((Source::Sky, sky::power(scene.sky, &disc)));
    }
    let total_lum: f32 = sources.iter().map(|s| luminance(s.1)).sum();
    let rho_bar = mean_reflectivity(scene, rays).clamp(0.0, 0.99);
    let mut set = VplSet {
        particles: n,
        mean_reflectivity: rho_bar,
        per_depth: Vec::new(),
        ..VplSet::default()
    };
    if sources.is_empty() || total_lum <= 0.0 {
        return set;
    }
    let cdf: Vec<f32> = sources
        .iter()
        .scan(0.0, |acc, s| {
            *acc += luminance(s.1) / total_lum;
            Some(*acc)
        })
        .collect();
    // Punctual lights enter once each, exactly (N identical point VPLs would be the same).
    if settings.first_generation {
        for (li, l) in scene.lights.iter().enumerate() {
            if l.is_punctual() && l.intensity > 0.0 {
                push(
                    &mut set,
                    Vpl {
                        position: l.position,
                        power: Vec3::ZERO,
                        kind: VplKind::Punctual { light: li as u32 },
                        depth: 0,
                        path: Vpl::EXACT,
                    },
                );
            }
        }
    }
    // Keller's generations: particles [⌊N·ρ̄^(k+1)⌋, ⌊N·ρ̄^k⌋) make k reflections.
    let max_depth = settings.max_depth.min(MAX_DEPTH);
    let mut start = n as f64;
    let mut end = n;
    let mut reflections = 0u32;
    while end > 0 {
        start *= rho_bar as f64;
        let first = (start as u32).min(end);
        for i in first..end {
            walk_one(
                scene,
                rays,
                emitters,
                settings,
                &sources,
                &cdf,
                i,
                reflections.min(max_depth),
                rho_bar,
                &disc,
                &sample,
                &mut set,
            );
        }
        reflections += 1;
        end = first;
        if rho_bar <= 0.0 {
            break;
        }
    }
    set
}

fn push(set: &mut VplSet, v: Vpl) {
    let d = v.depth as usize;
    if set.per_depth.len() <= d {
        set.per_depth.resize(d + 1, 0);
    }
    set.per_depth[d] += 1;
    set.vpls.push(v);
}

/// One particle's path: the start on its light, then `reflections` diffuse bounces.
#[allow(clippy::too_many_arguments)]
fn walk_one(
    scene: &Scene,
    rays: &RayScene,
    emitters: &Emitters,
    settings: &WalkSettings,
    sources: &[(Source, Vec3)],
    cdf: &[f32],
    i: u32,
    reflections: u32,
    rho_bar: f32,
    disc: &SceneDisc,
    sample: &dyn Fn(u32, usize) -> f32,
    set: &mut VplSet,
) {
    let n = settings.particles.max(1) as f32;
    let u0 = sample(i, 0);
    let k = cdf.partition_point(|&c| c <= u0).min(sources.len() - 1);
    let prev = if k == 0 { 0.0 } else { cdf[k - 1] };
    let prob = cdf[k] - prev;
    // What is left of dimension 0 inside the chosen source's interval, for choices within it.
    let u_rest = ((u0 - prev) / prob.max(1e-30)).clamp(0.0, 1.0 - f32::EPSILON);
    let (source, source_power) = sources[k];
    let mut power = source_power / (n * prob);
    let (u1, u2) = (
        Vec2::new(sample(i, 1), sample(i, 2)),
        Vec2::new(sample(i, 3), sample(i, 4)),
    );
    // Start point and direction, and the depth-0 VPL.
    let emission: Emission = match source {
        Source::Light(li) => scene.lights[li as usize].emit(u1, u2, disc),
        Source::Emitters => emitters.emit(rays, u_rest, u1, u2),
        Source::Sky => sky::emit(u1, u2, disc),
    };
    power *= emission.weight;
    let (origin, dir) = (emission.origin, emission.direction);
    let first = match emission.start {
        Start::Point => None,
        Start::Disc => Some(Vpl {
            position: origin,
            power: Vec3::ZERO,
            kind: VplKind::Directional {
                direction: dir,
                irradiance: power / disc.area(),
            },
            depth: 0,
            path: i,
        }),
        Start::Surface { normal } => Some(Vpl {
            position: origin,
            power,
            kind: VplKind::Diffuse { normal },
            depth: 0,
            path: i,
        }),
    };
    if settings.first_generation
        && let Some(v) = first
    {
        push(set, v);
    }
    // Reflections.
    let mut origin = origin;
    let mut dir = dir;
    for j in 1..=reflections {
        set.rays += 1;
        let Some(hit) = rays.closest_hit(origin, dir, 0.0, f32::INFINITY) else {
            return;
        };
        let info = rays.triangles[hit.triangle as usize];
        if !hit.front_face && !info.double_sided {
            return; // the back of a solid absorbs
        }
        let normal = if hit.front_face {
            info.normal
        } else {
            -info.normal
        };
        let y = origin + dir * hit.t;
        let albedo = albedo_at(scene, rays, &hit);
        power *= albedo / rho_bar;
        if luminance(power) <= 0.0 {
            return;
        }
        let position = rays.offset(y, normal);
        push(
            set,
            Vpl {
                position,
                power,
                kind: VplKind::Diffuse { normal },
                depth: j,
                path: i,
            },
        );
        if j == reflections {
            return;
        }
        let d = 5 + 2 * (j as usize - 1);
        dir = cosine_hemisphere(normal, Vec2::new(sample(i, d), sample(i, d + 1)));
        origin = position;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::testscenes::{CornellLight, cornell_box};

    #[test]
    fn vpl_count_stays_below_n_over_one_minus_rho() {
        let s = cornell_box(CornellLight::Area);
        let rays = RayScene::build(&s);
        let emitters = Emitters::collect(&s, &rays);
        for n in [100u32, 1000] {
            let set = walk(
                &s,
                &rays,
                &emitters,
                &WalkSettings {
                    particles: n,
                    sequence: Sequence::Halton,
                    seed: 0,
                    max_depth: MAX_DEPTH,
                    first_generation: true,
                },
            );
            let bound = n as f32 / (1.0 - set.mean_reflectivity);
            assert!(
                (set.vpls.len() as f32) < bound,
                "{} vs {bound}",
                set.vpls.len()
            );
            assert!(set.vpls.len() as u32 > n, "depth 0 plus reflections");
            // Generation sizes follow ⌊N·ρ̄^j⌋ (escaping particles only lower them).
            for (j, &count) in set.per_depth.iter().enumerate() {
                let expected = (n as f64 * (set.mean_reflectivity as f64).powi(j as i32)).floor();
                assert!(
                    count as f64 <= expected + 1.0,
                    "depth {j}: {count} vs {expected}"
                );
            }
        }
    }
}
