//! Texel density that follows the light: a pilot of the direct light estimates how much each
//! chart's lightmap loses to its texel size, and the texel budget is shared out again so the
//! charts that lose most get more texels and flat ones fewer, within the same total.
//!
//! This is adaptive subdivision ("refine where the radiosity gradient is high": Cohen,
//! Greenberg, Immel & Brock, *An efficient radiosity approach for realistic image synthesis*,
//! IEEE CG&A 1986; Cohen & Wallace, *Radiosity and Realistic Image Synthesis*, ch. 8) done on
//! lightmap charts, whose texels are the patches:
//!
//! 1. **Pilot.** Points are spread over each chart of each baked instance, one per
//!    [`TEXELS_PER_SAMPLE`] texels (at least one, at most [`MOST_CHART_SAMPLES`]). At each
//!    point p the direct light E of the point, spot, directional and rect lights is evaluated
//!    at p and at p ± δ along two directions of the surface, δ one texel (half a texel where
//!    a whole one leaves the triangle), with shadow rays to the [`SHADOWED_LIGHTS`] lights
//!    that give p most (the others unshadowed). The second difference
//!    E(p) − ½(E(p + δ) + E(p − δ)) is what linear interpolation between texels misses there:
//!    it grows as h² with the texel size h where the light is smooth and stays at half the
//!    jump where a shadow edge passes between the points.
//! 2. **Each chart's error** r_c is the RMS of the second differences (scaled to a whole texel)
//!    over its points, over every instance of its mesh.
//! 3. **Scales.** Chart c is drawn at s_c = k·√(r_c + [`FLOOR`]·Ē) times the density (Ē the
//!    mean direct light of the points), clamped to [[`LEAST_SCALE`], [`GREATEST_SCALE`]]
//!    (charts under [`THIN_CHART_TEXELS`] across are not drawn smaller), with k chosen so
//!    that Σ texels·s² is what it was: the preset's texel budget. The square root sits
//!    between the optimum for smooth light (error ∝ h², s ∝ r^⅓) and for shadow edges
//!    (squared error ∝ h, s ∝ r^⅔).
//!
//! Charts are scaled and packed again by [`Layout::with_chart_scales`]. What is left alone,
//! and why, is in the plan: a density set by the settings or the scene, a node's
//! `texel_density_scale` (its meshes keep their density), meshes that keep their own
//! `TEXCOORD_1`, and scenes lit only by the sky or by emissive surfaces (the pilot sees the
//! lights with a position or a direction).

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::Serialize;

use crate::bvh::RayScene;
use crate::color::luminance;
use crate::lights::LightSource;
use crate::plan::BakePlan;
use crate::raster::SurfacePoint;
use crate::sampling::{basis, hash_words, uniform_triangle, unit_float};
use crate::scene::Scene;
use crate::settings::BakeSettings;
use crate::unwrap::{Layout, UvOrigin};

/// Texels of a chart per pilot point.
pub const TEXELS_PER_SAMPLE: f64 = 4.0;
/// Most pilot points on one chart of one instance.
pub const MOST_CHART_SAMPLES: usize = 256;
/// Lights traced with shadow rays at each pilot point (those giving it most, each at least
/// 5% of the first); the others count unshadowed.
pub const SHADOWED_LIGHTS: usize = 4;
/// Least density scale of a chart.
pub const LEAST_SCALE: f32 = 0.5;
/// Texels across a chart's narrower side below which it is not drawn smaller: a strip a
/// texel or two wide drawn at ¾ has texel centres on its border only, and its light is
/// filled in from outside (a lit strip of OpenArena's `kaos` read 6% of its light).
pub const THIN_CHART_TEXELS: f32 = 4.0;
/// Greatest density scale of a chart.
pub const GREATEST_SCALE: f32 = 2.0;
/// Error every chart is taken to have, as a share of the mean direct light: indirect light,
/// contacts and noise the pilot does not see, so a chart in shade is not starved.
pub const FLOOR: f64 = 0.2;

/// What the pilot found and how the texels were shared out (in the report).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DensityReport {
    /// Pilot points.
    pub samples: u64,
    /// Shadow rays of the pilot.
    pub rays: u64,
    /// Charts given their own scale.
    pub charts: usize,
    /// Charts at the least scale.
    pub at_least: usize,
    /// Charts at the greatest scale.
    pub at_greatest: usize,
    /// Texels of those charts before (at one density), texels².
    pub texels_before: f64,
    /// Texels of those charts after.
    pub texels_after: f64,
    /// Mean direct light of the pilot points, lux.
    pub mean_irradiance: f64,
    /// Per mesh whose charts were scaled.
    pub meshes: Vec<MeshDensity>,
}

impl DensityReport {
    /// What the pilot did, in one line (the plan's reason and the stage's note).
    pub fn summary(&self) -> String {
        format!(
            "a pilot of {} points ({} rays) scaled {} charts by their direct light's error over a texel: {} at {LEAST_SCALE}×, {} at {GREATEST_SCALE}×; their texels {:.0} → {:.0}",
            self.samples,
            self.rays,
            self.charts,
            self.at_least,
            self.at_greatest,
            self.texels_before,
            self.texels_after
        )
    }
}

/// One mesh's chart scales and the errors they follow.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MeshDensity {
    /// Mesh name.
    pub mesh: String,
    /// Per chart: its density scale (per axis).
    pub scales: Vec<f32>,
    /// Per chart: the pilot's error r_c over the mean direct light Ē (`None`: no point of the
    /// chart could be measured, scale 1).
    pub errors: Vec<Option<f32>>,
}

/// Per mesh: whether its charts may take their own scales (unwrapped by lightbake, and no
/// baked instance of it has its own `texel_density_scale`).
fn adaptable_meshes(scene: &Scene, layout: &Layout) -> Vec<bool> {
    let mut ok: Vec<bool> = layout
        .meshes
        .iter()
        .map(|u| {
            u.as_ref()
                .is_some_and(|u| u.origin == UvOrigin::Xatlas && u.chart_count > 0)
        })
        .collect();
    for inst in scene.instances.iter().filter(|i| i.bake) {
        if inst.texel_density_scale != 1.0 {
            ok[inst.mesh] = false;
        }
    }
    ok
}

/// One chart of one instance in the pilot: squared error sum (lux²), measured points,
/// points, mean light (lux), rays.
#[derive(Clone, Copy, Default)]
struct ChartPilot {
    squared: f64,
    measured: u32,
    points: u32,
    light: f64,
    rays: u64,
}

/// The layout with each chart's density following the light (see the module docs), and what
/// was done; `Err` with the reason when nothing is scaled.
///
/// `rays` is the ray scene of `scene` (the source scene or its unwrapped copy: both give the
/// same triangles).
pub fn adapt(
    scene: &Scene,
    settings: &BakeSettings,
    plan: &BakePlan,
    layout: &Layout,
    rays: &RayScene,
) -> Result<(Layout, DensityReport), String> {
    let adaptable = adaptable_meshes(scene, layout);
    // Chart → its triangles, per adaptable mesh.
    let chart_triangles: Vec<Vec<Vec<u32>>> = layout
        .meshes
        .iter()
        .zip(&adaptable)
        .map(|(u, &ok)| match u {
            Some(u) if ok => {
                let mut out = vec![Vec::new(); u.chart_count as usize];
                for (t, &c) in u.triangle_charts.iter().enumerate() {
                    if let Some(list) = out.get_mut(c as usize) {
                        list.push(t as u32);
                    }
                }
                out
            }
            _ => Vec::new(),
        })
        .collect();
    let charts: usize = chart_triangles.iter().map(Vec::len).sum();
    if charts < 2 {
        return Err(
            "fewer than two charts of meshes lightbake unwraps at the scene's density".into(),
        );
    }
    let jobs: Vec<(usize, usize)> = scene
        .instances
        .iter()
        .enumerate()
        .filter(|(_, inst)| inst.bake && adaptable[inst.mesh])
        .flat_map(|(i, inst)| (0..chart_triangles[inst.mesh].len()).map(move |c| (i, c)))
        .collect();
    let results: Vec<ChartPilot> = jobs
        .par_iter()
        .map(|&(i, c)| {
            let mesh = scene.instances[i].mesh;
            chart_pilot(scene, layout, rays, plan, i, c, &chart_triangles[mesh][c])
        })
        .collect();

    // Per mesh and chart: Σ texels · mean e², Σ texels, measured or not.
    let texels: Vec<Vec<f64>> = layout
        .meshes
        .iter()
        .zip(&adaptable)
        .map(|(u, &ok)| match u {
            Some(u) if ok => u.chart_texels(),
            _ => Vec::new(),
        })
        .collect();
    // Per chart, its least scale: 1 for thin charts.
    let least: Vec<Vec<f64>> = layout
        .meshes
        .iter()
        .zip(&adaptable)
        .map(|(u, &ok)| match u {
            Some(u) if ok => u
                .chart_extents()
                .iter()
                .map(|e| {
                    (THIN_CHART_TEXELS / e.min_element().max(1e-3)).clamp(LEAST_SCALE, 1.0) as f64
                })
                .collect(),
            _ => Vec::new(),
        })
        .collect();
    let mut squared: Vec<Vec<f64>> = texels.iter().map(|t| vec![0.0; t.len()]).collect();
    let mut cost: Vec<Vec<f64>> = squared.clone();
    let mut measured: Vec<Vec<bool>> = texels.iter().map(|t| vec![false; t.len()]).collect();
    let (mut light, mut light_texels) = (0.0f64, 0.0f64);
    let mut report = DensityReport::default();
    for (&(i, c), r) in jobs.iter().zip(&results) {
        let m = scene.instances[i].mesh;
        let t = texels[m][c];
        report.samples += r.points as u64;
        report.rays += r.rays;
        cost[m][c] += t;
        if r.points > 0 {
            light += r.light / r.points as f64 * t;
            light_texels += t;
        }
        if r.measured > 0 {
            squared[m][c] += r.squared / r.measured as f64 * t;
            measured[m][c] = true;
        }
    }
    let mean = if light_texels > 0.0 {
        light / light_texels
    } else {
        0.0
    };
    if !(mean > 0.0 && mean.is_finite()) {
        return Err("the pilot found no direct light on the charts".into());
    }
    report.mean_irradiance = mean;
    // Each measured chart's error r (lux), weight √(r + floor·Ē) and scale.
    let error = |m: usize, c: usize| (squared[m][c] / cost[m][c].max(f64::MIN_POSITIVE)).sqrt();
    let weight = |m: usize, c: usize| (error(m, c) + FLOOR * mean).sqrt();
    let scale =
        |m: usize, c: usize, k: f64| (k * weight(m, c)).clamp(least[m][c], GREATEST_SCALE as f64);
    let k = budget_factor(&cost, &measured, scale);
    let mut scales: Vec<Option<Vec<f32>>> = vec![None; scene.meshes.len()];
    for m in 0..scene.meshes.len() {
        if texels[m].is_empty() {
            continue;
        }
        let mut s = vec![1.0f32; texels[m].len()];
        let mut errors = vec![None; texels[m].len()];
        for c in 0..s.len() {
            if measured[m][c] && cost[m][c] > 0.0 {
                s[c] = scale(m, c, k) as f32;
                errors[c] = Some((error(m, c) / mean) as f32);
                report.charts += 1;
                report.at_least += usize::from(s[c] <= LEAST_SCALE);
                report.at_greatest += usize::from(s[c] >= GREATEST_SCALE);
                report.texels_before += cost[m][c];
                report.texels_after += cost[m][c] * (s[c] as f64).powi(2);
            }
        }
        report.meshes.push(MeshDensity {
            mesh: scene.meshes[m].name.clone(),
            scales: s.clone(),
            errors,
        });
        scales[m] = Some(s);
    }
    Ok((layout.with_chart_scales(scene, settings, &scales), report))
}

/// k with Σ cost · scale(k)² = Σ cost over the measured charts (bisection on log k; every
/// chart's scale grows with k).
fn budget_factor(
    cost: &[Vec<f64>],
    measured: &[Vec<bool>],
    scale: impl Fn(usize, usize, f64) -> f64,
) -> f64 {
    let charts: Vec<(usize, usize, f64)> = cost
        .iter()
        .enumerate()
        .flat_map(|(m, cs)| {
            cs.iter()
                .enumerate()
                .filter(|&(c, &t)| measured[m][c] && t > 0.0)
                .map(|(c, &t)| (m, c, t))
                .collect::<Vec<_>>()
        })
        .collect();
    let total: f64 = charts.iter().map(|c| c.2).sum();
    let texels = |k: f64| -> f64 {
        charts
            .iter()
            .map(|&(m, c, t)| t * scale(m, c, k).powi(2))
            .sum()
    };
    let (mut lo, mut hi) = (-60.0f64, 60.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if texels(mid.exp()) < total {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    (0.5 * (lo + hi)).exp()
}

/// The pilot on chart `c` of instance `i` (triangles `tris` of its mesh).
fn chart_pilot(
    scene: &Scene,
    layout: &Layout,
    rays: &RayScene,
    plan: &BakePlan,
    i: usize,
    c: usize,
    tris: &[u32],
) -> ChartPilot {
    let inst = &scene.instances[i];
    let mesh = &scene.meshes[inst.mesh];
    let Some(unwrap) = layout.meshes[inst.mesh].as_ref() else {
        return ChartPilot::default();
    };
    let size = Vec2::new(unwrap.width as f32, unwrap.height as f32);
    let first = rays.instance_first_triangle[i];
    // Texel area of each triangle, and their running sum.
    let mut cumulative = Vec::with_capacity(tris.len());
    let mut total = 0.0f64;
    for &t in tris {
        let [a, b, d] =
            [0, 1, 2].map(|k| unwrap.uv1[unwrap.indices[3 * t as usize + k] as usize] * size);
        total += 0.5 * (b - a).perp_dot(d - a).abs() as f64;
        cumulative.push(total);
    }
    if total <= 0.0 {
        return ChartPilot::default();
    }
    let lights: Vec<&crate::scene::Light> = plan
        .lights_for(i)
        .iter()
        .map(|&l| &scene.lights[l as usize])
        .filter(|l| l.direct_is_baked())
        .collect();
    let n = ((total / TEXELS_PER_SAMPLE).round() as usize).clamp(1, MOST_CHART_SAMPLES);
    let normal_matrix = inst.normal_matrix();
    let mut out = ChartPilot::default();
    for k in 0..n {
        let key = [i as u32, c as u32, k as u32];
        let pick = (k as f64 + unit_float(hash_words(&[key[0], key[1], key[2], 0])) as f64)
            / n as f64
            * total;
        let j = cumulative
            .partition_point(|&x| x < pick)
            .min(tris.len() - 1);
        let t = tris[j] as usize;
        let g = first + t as u32;
        let w = rays.triangle_vertices(g);
        let texel_area = cumulative[j] - if j > 0 { cumulative[j - 1] } else { 0.0 };
        let world_area = rays.triangles[g as usize].area as f64;
        if texel_area <= 0.0 || world_area <= 0.0 {
            continue;
        }
        let bary = uniform_triangle(Vec2::new(
            unit_float(hash_words(&[key[0], key[1], key[2], 1])),
            unit_float(hash_words(&[key[0], key[1], key[2], 2])),
        ));
        let at = |b: Vec2| w[0] * (1.0 - b.x - b.y) + w[1] * b.x + w[2] * b.y;
        let p = at(bary);
        // The side the lightmap shows: the geometric normal turned to the shading normal.
        let shading = normal_matrix * mesh.shading_normal(t, bary);
        let mut normal = rays.triangles[g as usize].normal;
        if normal.dot(shading) < 0.0 {
            normal = -normal;
        }
        let point = |q: Vec3| SurfacePoint {
            position: q,
            normal,
            geometric_normal: normal,
            triangle: g,
            bary,
        };
        // The lights giving p most are traced; the rest count unshadowed.
        let centre = point(p);
        let mut gives: Vec<(f32, usize)> = lights
            .iter()
            .enumerate()
            .filter_map(|(l, light)| {
                let e = light.incident(&centre, Vec2::splat(0.5), rays)?;
                Some((luminance(e.irradiance), l))
            })
            .collect();
        gives.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let strongest = gives.first().map_or(0.0, |g| g.0);
        let traced: Vec<usize> = gives
            .iter()
            .take(SHADOWED_LIGHTS)
            .filter(|g| g.0 >= 0.05 * strongest && g.0 > 0.0)
            .map(|g| g.1)
            .collect();
        let mut traced_rays = 0u64;
        let mut light_at = |q: Vec3| -> f64 {
            let sp = point(q);
            let origin = rays.offset(q, normal);
            let mut e = 0.0f64;
            for (l, light) in lights.iter().enumerate() {
                let Some(inc) = light.incident(&sp, Vec2::splat(0.5), rays) else {
                    continue;
                };
                if traced.contains(&l) {
                    traced_rays += 1;
                    if !inc.visible(rays, origin) {
                        continue;
                    }
                }
                e += luminance(inc.irradiance) as f64;
            }
            e
        };
        let e0 = light_at(p);
        out.points += 1;
        out.light += e0;
        // Second differences along two directions, each over the largest step (one texel,
        // else half) that stays on the triangle.
        let h = (world_area / texel_area).sqrt() as f32;
        let (t1, t2) = basis(normal);
        let mut squared = 0.0f64;
        let mut directions = 0;
        for d in [t1, t2] {
            for step in [1.0f32, 0.5] {
                let delta = d * (h * step);
                let (Some(_), Some(_)) = (barycentric(&w, p + delta), barycentric(&w, p - delta))
                else {
                    continue;
                };
                let second = e0 - 0.5 * (light_at(p + delta) + light_at(p - delta));
                squared += (second / (step * step) as f64).powi(2);
                directions += 1;
                break;
            }
        }
        out.rays += traced_rays;
        if directions > 0 {
            out.squared += squared * 2.0 / directions as f64;
            out.measured += 1;
        }
    }
    out
}

/// Barycentric coordinates of `q` (in the triangle's plane) when it lies inside `w`.
fn barycentric(w: &[Vec3; 3], q: Vec3) -> Option<Vec2> {
    let (e1, e2, r) = (w[1] - w[0], w[2] - w[0], q - w[0]);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = d11 * d22 - d12 * d12;
    if det <= 0.0 {
        return None;
    }
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let b1 = (d22 * r1 - d12 * r2) / det;
    let b2 = (d11 * r2 - d12 * r1) / det;
    (b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0).then_some(Vec2::new(b1, b2))
}
