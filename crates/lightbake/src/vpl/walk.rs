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
use crate::direct::{Emitters, luminance};
use crate::sampling::{
    Sequence, basis, concentric_disc, cosine_hemisphere, uniform_cone, uniform_triangle,
};
use crate::scene::{LightKind, Scene};

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

/// Highest depth the sequence's 64 dimensions allow.
pub const MAX_DEPTH: u32 = 29;

/// One emitting thing the particles start from, with its power (lumens, RGB).
#[derive(Clone, Copy, Debug)]
enum Source {
    Light(u32),
    Emitters,
    Sky,
}

/// Albedo of the surface at a hit (material factor × texture at UV0 × (1 − metallic)).
pub fn albedo_at(scene: &Scene, rays: &RayScene, hit: &Hit) -> Vec3 {
    let info = rays.triangles[hit.triangle as usize];
    let inst = &scene.instances[info.instance as usize];
    let material = scene.material_of(inst.mesh);
    let mut albedo = material.base_color.truncate() * (1.0 - material.metallic);
    if let (Some(t), Some(uv0)) = (
        material.base_color_texture,
        scene.meshes[inst.mesh].uv0.as_ref(),
    ) {
        let mesh = &scene.meshes[inst.mesh];
        let [a, b, c] = mesh.triangle(info.local as usize);
        let uv = uv0[a] * (1.0 - hit.u - hit.v) + uv0[b] * hit.u + uv0[c] * hit.v;
        albedo *= scene.textures[t.texture].sample_srgb(uv).truncate();
    }
    albedo
}

/// Keller's ρ̄: the area-weighted mean of the albedo's luminance over every triangle.
pub fn mean_reflectivity(scene: &Scene, rays: &RayScene) -> f32 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for info in &rays.triangles {
        let inst = &scene.instances[info.instance as usize];
        let m = scene.material_of(inst.mesh);
        let mut albedo = m.base_color.truncate() * (1.0 - m.metallic);
        if let Some(t) = m.base_color_texture {
            albedo *= scene.textures[t.texture].mean_srgb().truncate();
        }
        num += luminance(albedo) as f64 * info.area as f64;
        den += info.area as f64;
    }
    if den > 0.0 { (num / den) as f32 } else { 0.0 }
}

/// Total power of the cone falloff of a spot light per candela: ∫ S(θ) dω over the cone.
fn spot_solid_angle(inner: f32, outer: f32) -> f32 {
    let (ci, co) = (inner.cos(), outer.cos());
    let scale = 1.0 / (ci - co).max(1e-4);
    let steps = 512;
    let mut sum = 0.0f32;
    for k in 0..steps {
        let theta = outer * (k as f32 + 0.5) / steps as f32;
        let a = ((theta.cos() - co) * scale).clamp(0.0, 1.0);
        sum += a * a * theta.sin() * outer / steps as f32;
    }
    std::f32::consts::TAU * sum
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
    let centre = 0.5 * (rays.bounds.0 + rays.bounds.1);
    let radius = 0.5 * (rays.bounds.1 - rays.bounds.0).length().max(1e-6);
    let disc_area = std::f32::consts::PI * radius * radius;

    // Sources and their power (lumens, RGB).
    let mut sources: Vec<(Source, Vec3)> = Vec::new();
    for (li, l) in scene.lights.iter().enumerate() {
        let power = match l.kind {
            LightKind::Point => l.color * l.intensity * 4.0 * std::f32::consts::PI,
            LightKind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => l.color * l.intensity * spot_solid_angle(inner_cone_angle, outer_cone_angle),
            LightKind::Directional { .. } => l.color * l.intensity * disc_area,
        };
        if luminance(power) > 0.0 {
            sources.push((Source::Light(li as u32), power));
        }
    }
    if !emitters.is_empty() {
        let p = emitters.list.iter().fold(Vec3::ZERO, |s, e| {
            s + e.radiance * (std::f32::consts::PI * e.area * if e.two_sided { 2.0 } else { 1.0 })
        });
        sources.push((Source::Emitters, p));
    }
    if scene.sky.max_element() > 0.0 {
        sources.push((
            Source::Sky,
            scene.sky * (4.0 * std::f32::consts::PI * disc_area),
        ));
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
            if matches!(l.kind, LightKind::Point | LightKind::Spot { .. }) && l.intensity > 0.0 {
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
                centre,
                radius,
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

/// A directional particle (sun or sky) entering along `d` through the disc of `radius` around
/// `centre` that covers the scene: its start outside the scene, its direction, and the
/// depth-0 VPL carrying `power` spread over the disc as irradiance.
fn disc_start(
    d: Vec3,
    u: Vec2,
    centre: Vec3,
    radius: f32,
    power: Vec3,
    path: u32,
) -> (Vec3, Vec3, Option<Vpl>) {
    let (t, b) = basis(d);
    let disc = concentric_disc(u) * radius;
    let o = centre + t * disc.x + b * disc.y - d * (2.0 * radius);
    let irradiance = power / (std::f32::consts::PI * radius * radius);
    let vpl = Vpl {
        position: o,
        power: Vec3::ZERO,
        kind: VplKind::Directional {
            direction: d,
            irradiance,
        },
        depth: 0,
        path,
    };
    (o, d, Some(vpl))
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
    centre: Vec3,
    radius: f32,
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
    let (origin, dir, first): (Vec3, Vec3, Option<Vpl>) = match source {
        Source::Light(li) => {
            let l = &scene.lights[li as usize];
            match l.kind {
                LightKind::Point => {
                    let d = uniform_cone(Vec3::Z, -1.0, u2);
                    (l.position, d, None)
                }
                LightKind::Spot {
                    inner_cone_angle,
                    outer_cone_angle,
                } => {
                    // Uniform in the outer cone, weighted by the falloff.
                    let d = uniform_cone(l.direction, outer_cone_angle.cos(), u2);
                    let (ci, co) = (inner_cone_angle.cos(), outer_cone_angle.cos());
                    let a = ((d.dot(l.direction) - co) / (ci - co).max(1e-4)).clamp(0.0, 1.0);
                    let solid = std::f32::consts::TAU * (1.0 - co);
                    let falloff_mean = spot_solid_angle(inner_cone_angle, outer_cone_angle) / solid;
                    power *= a * a / falloff_mean.max(1e-12);
                    (l.position, d, None)
                }
                LightKind::Directional { angular_radius } => {
                    let d = if angular_radius > 0.0 {
                        uniform_cone(l.direction, angular_radius.cos(), u2)
                    } else {
                        l.direction
                    };
                    disc_start(d, u1, centre, radius, power, i)
                }
            }
        }
        Source::Emitters => {
            // The triangle by power, from the rest of dimension 0; the point from 1–2.
            let (e, _) = emitters.pick(u_rest);
            let em = &emitters.list[e];
            let b = uniform_triangle(u1);
            let y =
                em.vertices[0] * (1.0 - b.x - b.y) + em.vertices[1] * b.x + em.vertices[2] * b.y;
            let mut normal = em.normal;
            if em.two_sided && u2.x < 0.5 {
                normal = -normal;
            }
            let d = cosine_hemisphere(
                normal,
                Vec2::new(
                    if em.two_sided {
                        (u2.x * 2.0).fract()
                    } else {
                        u2.x
                    },
                    u2.y,
                ),
            );
            let o = rays.offset(y, normal);
            (
                o,
                d,
                Some(Vpl {
                    position: o,
                    power,
                    kind: VplKind::Diffuse { normal },
                    depth: 0,
                    path: i,
                }),
            )
        }
        Source::Sky => {
            let d = uniform_cone(Vec3::Z, -1.0, u2);
            disc_start(d, u1, centre, radius, power, i)
        }
    };
    if settings.first_generation {
        if let Some(v) = first {
            push(set, v);
        }
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

    #[test]
    fn spot_solid_angle_matches_hard_cone() {
        // Inner = outer: a hard cone of solid angle 2π(1 − cos θ).
        let s = spot_solid_angle(0.5, 0.5 + 1e-4);
        let hard = std::f32::consts::TAU * (1.0 - 0.5f32.cos());
        assert!((s - hard).abs() / hard < 0.01, "{s} {hard}");
    }
}
