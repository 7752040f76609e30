//! Direct light against known answers: point light E = I·cosθ/r², spot cone edges,
//! directional E = E⊥·cosθ (hard and soft sun), umbra and unchanged texels around an occluder,
//! and a small area light against the closed-form point-to-rectangle form factor.
//!
//! Texels store E/π; every comparison divides the analytic irradiance by π.

mod common;

use std::f32::consts::PI;

use common::{add, bake, rel, settings, texels, uv_plane};
use glam::{Affine3A, Vec3};
use lightbake::analysis::points::{ScorePoint, sample_bake};
use lightbake::scene::testscenes::{cuboid, quad};
use lightbake::scene::{Light, LightKind, Material, Mesh, Scene};

fn point_light(position: Vec3, intensity: f32) -> Light {
    Light {
        name: "lamp".into(),
        kind: LightKind::Point,
        color: Vec3::new(1.0, 0.5, 0.25),
        intensity,
        range: None,
        position,
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    }
}

#[test]
fn point_light_over_plane_matches_inverse_square_law() {
    let (mut s, plane) = white_floor(4.0);
    let light = point_light(Vec3::new(0.3, 1.5, -0.2), 100.0);
    s.lights.push(light.clone());
    let out = bake(&s, &settings(16.0, 16));
    let samples = texels(&out, plane);
    assert_eq!(samples.len(), 64 * 64);
    let mut worst = 0.0f32;
    for t in &samples {
        let to = light.position - t.position;
        let r2 = to.length_squared();
        let cos = t.normal.dot(to.normalize());
        let expected = light.color * (light.intensity * cos / r2) / PI;
        for k in 0..3 {
            worst = worst.max(rel(t.value[k], expected[k]));
        }
    }
    assert!(worst < 0.01, "worst relative error {worst}");
}

/// A scene of one white `size × size` m floor facing up (planar TEXCOORD_1), and its instance.
fn white_floor(size: f32) -> (Scene, usize) {
    let mut s = Scene::default();
    let plane = add(
        &mut s,
        uv_plane("floor", size),
        Vec3::ONE,
        Affine3A::IDENTITY,
        true,
    );
    (s, plane)
}

/// The exact direct light of `lights` at a texel (E/π as the lightmap stores it, luminance),
/// with nothing in the way.
fn inverse_square_sum(lights: &[Light], t: &common::TexelSample) -> f32 {
    lights
        .iter()
        .map(|l| {
            let to = l.position - t.position;
            let cos = t.normal.dot(to.normalize()).max(0.0);
            lightbake::color::luminance(l.color) * l.intensity * cos / to.length_squared()
        })
        .sum::<f32>()
        / PI
}

/// `n` point lights over a 4 m floor, baked with one light per footprint sample: the texels
/// are unbiased (their mean matches Σ I·cosθ/r² within 2%), every texel is lit, and the
/// bake's own estimate sees the sampling noise.
fn many_point_lights_match_the_inverse_square_sum(n: usize) {
    let (mut s, plane) = white_floor(4.0);
    let columns = (n as f32).sqrt().ceil() as usize;
    let lights: Vec<Light> = (0..n)
        .map(|k| {
            let x = (k % columns) as f32 / columns as f32 * 3.8 - 1.9;
            let z = (k / columns) as f32 / columns as f32 * 3.6 - 1.8;
            point_light(
                Vec3::new(x, 0.6 + 0.1 * (k % 3) as f32, z),
                (0.2 + 0.05 * (k % 5) as f32) * 300.0 / n as f32,
            )
        })
        .collect();
    s.lights.extend(lights.iter().cloned());
    let out = bake(&s, &settings(8.0, 64));
    let samples = texels(&out, plane);
    let (mut sum_baked, mut sum_exact, mut worst) = (0.0f64, 0.0f64, 0.0f32);
    for t in &samples {
        let exact = inverse_square_sum(&lights, t);
        let baked = lightbake::color::luminance(t.value);
        assert!(baked > 0.0, "a lit texel is black");
        sum_baked += baked as f64;
        sum_exact += exact as f64;
        worst = worst.max(rel(baked, exact));
    }
    let mean_error = (sum_baked / sum_exact - 1.0).abs();
    let stated = out.report.error.as_ref().map_or(0.0, |e| e.relative_rms);
    assert!(mean_error < 0.02, "mean off by {mean_error}");
    // One light per sample is noisy, texel by texel; the bake's own estimate says how much.
    assert!(
        stated > 0.005,
        "the estimate sees the sampling noise: {stated}"
    );
    println!("{n} lights: mean {mean_error:.4}, worst texel {worst:.3}, stated error {stated:.3}");
}

/// 300 lights: each texel weighs the lights itself (`direct::light_choice`).
#[test]
fn many_point_lights_picked_by_each_texel_match_the_inverse_square_sum() {
    many_point_lights_match_the_inverse_square_sum(300);
}

/// 1 100 lights, more than a texel weighs itself: the light tree picks.
#[test]
fn many_point_lights_picked_from_the_light_tree_match_the_inverse_square_sum() {
    many_point_lights_match_the_inverse_square_sum(1100);
}

/// One lamp lights a floor under a slab; 100 brighter lamps sit above the slab, in front of
/// the floor's plane but unable to reach it (the many lights of a level, most of them in other
/// rooms). With one light per footprint sample, the samples must go to the lamp the texel
/// sees: every texel within 50% of the one lamp's inverse-square light at 16 samples, 12% RMS
/// (a texel's samples give the hidden lamps at most a tenth of them). (The
/// light tree alone, which weighs lights by power over distance² and cannot see the slab,
/// gave this floor black texels next to ones several times too bright.)
#[test]
fn many_lights_behind_an_occluder_do_not_take_the_samples_of_the_one_that_is_seen() {
    let (mut s, plane) = white_floor(2.0);
    let slab = quad(
        "slab",
        [
            Vec3::new(-3.0, 1.0, -3.0),
            Vec3::new(3.0, 1.0, -3.0),
            Vec3::new(3.0, 1.0, 3.0),
            Vec3::new(-3.0, 1.0, 3.0),
        ],
        Vec3::NEG_Y,
    );
    add(&mut s, slab, Vec3::splat(0.5), Affine3A::IDENTITY, true);
    let lamp = point_light(Vec3::new(0.3, 0.8, -0.2), 2.0);
    s.lights.push(lamp.clone());
    for k in 0..100 {
        let (x, z) = ((k % 10) as f32 * 0.5 - 2.25, (k / 10) as f32 * 0.5 - 2.25);
        s.lights.push(point_light(Vec3::new(x, 1.2, z), 20.0));
    }
    let mut settings = settings(16.0, 16);
    settings.method = lightbake::settings::Method::Direct;
    let out = bake(&s, &settings);
    let samples = texels(&out, plane);
    assert!(samples.len() > 500);
    let errors: Vec<f32> = samples
        .iter()
        .map(|t| {
            rel(
                lightbake::color::luminance(t.value),
                inverse_square_sum(std::slice::from_ref(&lamp), t),
            )
        })
        .collect();
    let worst = errors.iter().copied().fold(0.0f32, f32::max);
    let rms = (errors.iter().map(|e| e * e).sum::<f32>() / errors.len() as f32).sqrt();
    println!("worst texel {worst:.3}, RMS {rms:.4}");
    assert!(worst < 0.5 && rms < 0.12, "worst texel {worst}, RMS {rms}");
}

#[test]
fn spot_light_respects_its_cone() {
    let (mut s, plane) = white_floor(6.0);
    let (inner, outer) = (0.3f32, 0.5f32);
    let position = Vec3::new(0.0, 2.0, 0.0);
    s.lights.push(Light {
        name: "spot".into(),
        kind: LightKind::Spot {
            inner_cone_angle: inner,
            outer_cone_angle: outer,
        },
        color: Vec3::ONE,
        intensity: 50.0,
        range: None,
        position,
        direction: Vec3::NEG_Y,
        bake: lightbake::scene::LightBake::Full,
    });
    let out = bake(&s, &settings(12.0, 16));
    let half_texel = 0.5 * 6.0 / 72.0 * 2f32.sqrt();
    let (mut inside, mut outside, mut between) = (0, 0, 0);
    for t in texels(&out, plane) {
        let to = t.position - position;
        let angle = to.normalize().dot(Vec3::NEG_Y).acos();
        // Angular half-width of the texel footprint seen from the light.
        let slack = (half_texel / to.length()) * 1.2;
        let full = 50.0 * t.normal.dot(-to.normalize()) / to.length_squared() / PI;
        if angle - slack > outer {
            assert_eq!(
                t.value,
                Vec3::ZERO,
                "texel {:?} outside the cone is lit",
                t.local
            );
            outside += 1;
        } else if angle + slack < inner {
            assert!(
                rel(t.value.x, full) < 0.01,
                "texel {:?}: {} vs {}",
                t.local,
                t.value.x,
                full
            );
            inside += 1;
        } else {
            assert!(t.value.x >= 0.0 && t.value.x <= full * 1.01);
            between += 1;
        }
    }
    assert!(
        inside > 100 && outside > 1000 && between > 50,
        "{inside} {outside} {between}"
    );
}

#[test]
fn directional_light_gives_uniform_cosine_irradiance() {
    for angular_radius in [0.0f32, 0.1] {
        let mut s = Scene::default();
        let plane = add(
            &mut s,
            uv_plane("floor", 2.0),
            Vec3::ONE,
            Affine3A::IDENTITY,
            true,
        );
        let direction = Vec3::new(0.5, -0.8, 0.2).normalize();
        s.lights.push(Light {
            name: "sun".into(),
            kind: LightKind::Directional { angular_radius },
            color: Vec3::ONE,
            intensity: 10_000.0,
            range: None,
            position: Vec3::ZERO,
            direction,
            bake: lightbake::scene::LightBake::Full,
        });
        let out = bake(&s, &settings(16.0, 16));
        // The mean cosine over a uniform cone of half-angle α about a direction at angle θ
        // from the normal (cone above the horizon) is cosθ·(1 + cos α)/2.
        let cos = -direction.y * (1.0 + angular_radius.cos()) / 2.0;
        let expected = 10_000.0 * cos / PI;
        let samples = texels(&out, plane);
        // Hard sun: exact. Soft sun: 16 stratified cone samples per texel, so each texel is
        // within 2% and the plane's mean (16 × 1024 samples) within 0.1%.
        let per_texel = if angular_radius > 0.0 { 0.02 } else { 1e-5 };
        for t in &samples {
            assert!(
                rel(t.value.x, expected) < per_texel,
                "radius {angular_radius}: texel {:?} {} vs {expected}",
                t.local,
                t.value.x
            );
        }
        let mean = samples.iter().map(|t| t.value.x as f64).sum::<f64>() / samples.len() as f64;
        assert!(
            rel(mean as f32, expected) < 1e-3,
            "radius {angular_radius}: mean {mean} vs {expected}"
        );
    }
}

#[test]
fn occluder_casts_an_umbra_and_leaves_the_rest_unchanged() {
    let light_pos = Vec3::new(0.0, 2.0, 0.0);
    let build = |with_occluder: bool| {
        let mut s = Scene::default();
        add(
            &mut s,
            uv_plane("floor", 4.0),
            Vec3::ONE,
            Affine3A::IDENTITY,
            true,
        );
        s.lights.push(point_light(light_pos, 40.0));
        if with_occluder {
            // A 0.4 m square card at y = 1: its shadow is the 0.8 m square centred below.
            let card = cuboid(
                "card",
                Vec3::new(-0.2, 0.99, -0.2),
                Vec3::new(0.2, 1.0, 0.2),
                false,
            );
            add(&mut s, card, Vec3::ONE, Affine3A::IDENTITY, false);
        }
        s
    };
    let open = bake(&build(false), &settings(16.0, 16));
    let shadowed = bake(&build(true), &settings(16.0, 16));
    let (a, b) = (texels(&open, 0), texels(&shadowed, 0));
    assert_eq!(a.len(), b.len());
    let half_texel = 0.5 * 4.0 / 64.0;
    let (mut umbra, mut unchanged) = (0, 0);
    for (ta, tb) in a.iter().zip(&b) {
        let (x, z) = (tb.position.x.abs(), tb.position.z.abs());
        // Shadow of the card's top (y = 1, half-width 0.2) from y = 2 onto y = 0: half-width 0.4;
        // its bottom (y = 0.99) casts a slightly larger one.
        let edge_inner = 0.4;
        let edge_outer = 0.2 * 2.0 / 1.01;
        if x + half_texel < edge_inner && z + half_texel < edge_inner {
            assert_eq!(tb.value, Vec3::ZERO, "umbra texel {:?} is lit", tb.local);
            umbra += 1;
        } else if x - half_texel > edge_outer || z - half_texel > edge_outer {
            assert_eq!(
                ta.value, tb.value,
                "texel {:?} outside the shadow changed",
                tb.local
            );
            unchanged += 1;
        }
    }
    // The umbra is 0.8 m square (12.8 texels across at 16 texels/m).
    assert!(umbra > 120 && unchanged > 3000, "{umbra} {unchanged}");
}

/// Howell's catalogue B-3: a differential element under one corner of a parallel a × b
/// rectangle at distance c.
fn corner_parallel(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / (2.0 * std::f64::consts::PI)
}

/// Form factor from a point at (px, pz) on the floor to the rectangle [x0,x1]×[z0,z1] at
/// height c, by superposition of corner rectangles (signed extents).
fn rect_form_factor(px: f64, pz: f64, x0: f64, x1: f64, z0: f64, z1: f64, c: f64) -> f64 {
    let f = |dx: f64, dz: f64| corner_parallel(dx.abs(), dz.abs(), c) * dx.signum() * dz.signum();
    f(x1 - px, z1 - pz) - f(x0 - px, z1 - pz) - f(x1 - px, z0 - pz) + f(x0 - px, z0 - pz)
}

fn area_light_scene(luminance: f32) -> (Scene, usize) {
    let mut s = Scene::default();
    let floor = add(
        &mut s,
        uv_plane("floor", 2.0),
        Vec3::ONE,
        Affine3A::IDENTITY,
        true,
    );
    let emitter = s.add_material(Material::emitter("lamp", Vec3::splat(luminance)));
    let h = 0.1;
    let m = s.add_mesh(Mesh {
        material: Some(emitter),
        ..quad(
            "lamp",
            [
                Vec3::new(-h, 1.0, -h),
                Vec3::new(h, 1.0, -h),
                Vec3::new(h, 1.0, h),
                Vec3::new(-h, 1.0, h),
            ],
            Vec3::NEG_Y,
        )
    });
    let mut inst = lightbake::scene::Instance::new("lamp", m, Affine3A::IDENTITY);
    inst.bake = false;
    s.instances.push(inst);
    (s, floor)
}

#[test]
fn small_area_light_matches_closed_form_rectangle_form_factor() {
    let luminance = 1000.0;
    let (s, floor) = area_light_scene(luminance);
    let expected = |t: &common::TexelSample| {
        let f = rect_form_factor(
            t.position.x as f64,
            t.position.z as f64,
            -0.1,
            0.1,
            -0.1,
            0.1,
            1.0,
        );
        // E = π·L·F, stored E/π = L·F.
        luminance * f as f32
    };
    // Closed form + ratio estimator (the default for few emitters): every texel within 2%.
    let out = bake(&s, &settings(16.0, 16));
    let mut worst = 0.0f32;
    for t in texels(&out, floor) {
        worst = worst.max(rel(t.value.x, expected(&t)));
    }
    assert!(worst < 0.02, "closed form path: worst {worst}");

    // Power sampling (many emitters): the RMS error over the plane is within 2%.
    let mut st = settings(16.0, 256);
    st.direct.max_closed_form_emitters = 0;
    let out = bake(&s, &st);
    let samples = texels(&out, floor);
    let rms = (samples
        .iter()
        .map(|t| rel(t.value.x, expected(t)).powi(2))
        .sum::<f32>()
        / samples.len() as f32)
        .sqrt();
    assert!(rms < 0.02, "sampled path: RMS {rms}");
}

#[test]
fn sky_irradiance_on_an_open_plane_is_pi_l() {
    let (mut s, plane) = white_floor(1.0);
    s.sky = Vec3::new(100.0, 200.0, 300.0);
    let out = bake(&s, &settings(16.0, 4));
    for t in texels(&out, plane) {
        // Nothing occludes the upper hemisphere: E = π·L, stored E/π = L.
        assert!(
            (t.value - s.sky).abs().max_element() < 1e-3,
            "{:?}",
            t.value
        );
    }
}

/// A wall standing on a floor, lit from one side by a point light below the wall's top: floor
/// texels entirely on the far side get no light (no leak under the wall), and texels touching
/// the wall's foot on the lit side are not black (their sample points are moved out from under
/// the wall), for a wall thicker than a texel and one thinner than a texel. Behind the wall
/// thicker than a texel, the floor as the GPU shows it (bilinearly) is dark right up to the
/// wall, for one 3 and one 1.5 texels thick: the texels hidden under the wall are fitted to
/// the visible floor on each side (`lightmap::contacts`), not filled with both sides' light.
/// (A wall thinner than a texel shares a valid texel between its sides, which shows a little
/// of the lit side behind it.)
#[test]
fn walls_do_not_leak_and_their_feet_are_not_black() {
    let texel = 1.0 / 32.0;
    // (thickness, centre): the 1.5-texel wall is off the texel grid by half a texel, so one
    // floor texel lies wholly under it between a lit and a dark neighbour.
    for (thickness, c) in [(0.1f32, 0.0f32), (1.5 * texel, 0.5 * texel), (0.01, 0.0)] {
        let mut s = Scene::default();
        let floor = add(
            &mut s,
            uv_plane("floor", 2.0),
            Vec3::ONE,
            Affine3A::IDENTITY,
            true,
        );
        let h = thickness / 2.0;
        let wall = cuboid(
            "wall",
            Vec3::new(c - h, 0.0, -1.2),
            Vec3::new(c + h, 1.0, 1.2),
            true,
        );
        add(&mut s, wall, Vec3::ONE, Affine3A::IDENTITY, true);
        let light = point_light(Vec3::new(-0.6, 0.5, 0.0), 10.0);
        s.lights.push(light.clone());
        let out = bake(&s, &settings(32.0, 16));
        let lit_at = |x: f32, z: f32| {
            let to = light.position - Vec3::new(x, 0.0, z);
            light.color.x * light.intensity * to.normalize().y / to.length_squared() / PI
        };
        let (mut dark, mut foot) = (0, 0);
        for t in texels(&out, floor) {
            let x = t.position.x - c;
            if x - texel / 2.0 > h {
                assert_eq!(
                    t.value,
                    Vec3::ZERO,
                    "wall {thickness}: texel at x = {x} behind the wall is lit"
                );
                dark += 1;
            } else if x + texel / 2.0 > -h && x - texel / 2.0 < -h {
                // The texel straddles the lit face of the wall.
                let expected = lit_at(c - h, t.position.z);
                assert!(
                    t.value.x > 0.5 * expected,
                    "wall {thickness}: texel at x = {x} at the wall's foot is {} (lit floor there: {expected})",
                    t.value.x
                );
                foot += 1;
            }
        }
        assert!(dark > 1000 && foot >= 60, "{dark} {foot}");
        if thickness < texel {
            continue;
        }
        // The floor as the GPU shows it, along lines across the wall.
        let shown = |x: f32, z: f32| {
            sample_bake(
                &out,
                &ScorePoint {
                    instance: floor as u32,
                    position: Vec3::new(x, 0.0, z),
                    normal: Vec3::Y,
                    reference: Vec3::ZERO,
                    variance: 0.0,
                },
            )
            .expect("the floor is baked")
            .x
        };
        for k in 0..40 {
            let z = -0.8 + 1.6 * k as f32 / 39.0;
            let near = lit_at(c - h, z);
            let behind = shown(c + h + 0.05 * texel, z);
            assert!(
                behind < 0.05 * near,
                "wall {thickness}: the floor just behind the wall at z = {z} shows {behind} (the lit foot: {near})"
            );
            let x = c - h - 0.2 * texel;
            let front = shown(x, z);
            assert!(
                front > 0.5 * lit_at(x, z),
                "wall {thickness}: the lit floor at x = {x}, z = {z} shows {front} (lit: {})",
                lit_at(x, z)
            );
        }
    }
}
