//! Stability on extreme inputs: the same scene at 1 mm, 1 m and 10 km; light intensities from
//! 10⁻⁶ to 10⁹ (and what happens beyond half-float range). Each case checks finite output and
//! agreement with a known answer. The table of cases and results is in `docs/stability.md`.

mod common;

use common::bake;
use glam::{Affine3A, Vec3};
use lightbake::BakeOutput;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::{BakeSettings, Method};
use lightbake::study::relative_rms_error;

/// `scene` with every length multiplied by `s` (instances, lights, ranges).
fn scaled(scene: &Scene, s: f32) -> Scene {
    let mut out = scene.clone();
    for inst in &mut out.instances {
        inst.transform = Affine3A::from_scale(Vec3::splat(s)) * inst.transform;
    }
    for l in &mut out.lights {
        l.position *= s;
        l.range = l.range.map(|r| r * s);
    }
    out
}

fn settings(method: Method, density: f32) -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.method = method;
    s.texel_density = density;
    s.texel_density_from_scene = false;
    s
}

fn all_finite(out: &BakeOutput) -> bool {
    out.pages
        .iter()
        .all(|p| p.texels.iter().all(|t| t.is_finite()))
}

#[test]
fn the_same_scene_at_1_mm_1_m_and_10_km_gives_the_same_lightmap() {
    // The area-lit Cornell box: emitted luminance does not depend on scale, so neither does
    // the irradiance anywhere. The texel density follows the scale so the layout is the same.
    let base = cornell_box(CornellLight::Area);
    let reference = bake(&base, &settings(Method::Radiosity, 32.0));
    for s in [1e-3f32, 1e4] {
        let out = bake(&scaled(&base, s), &settings(Method::Radiosity, 32.0 / s));
        assert!(all_finite(&out), "scale {s}: non-finite texels");
        assert_eq!(
            out.report.texels.patches, reference.report.texels.patches,
            "scale {s}: the layout changed"
        );
        let diff = relative_rms_error(&out.pages, &reference.pages);
        println!(
            "scale {s}: {} patches, {} moved, {} invalid; relative RMS difference {diff:.5}",
            out.report.texels.patches, out.report.texels.moved, out.report.texels.invalid
        );
        assert!(
            diff < 0.01,
            "scale {s}: lightmap differs from the 1 m bake by {:.2}%",
            100.0 * diff
        );
    }
}

#[test]
fn light_intensities_from_1e_minus_6_to_1e9_scale_the_lightmap_linearly() {
    // The point-lit Cornell box, direct light and radiosity: the equations are linear in the
    // light, so the lightmap must scale with it exactly up to float rounding.
    let base = cornell_box(CornellLight::Point);
    let s = settings(Method::Radiosity, 24.0);
    let reference = bake(&base, &s);
    for k in [1e-6f32, 1e3, 1e9] {
        let mut scene = base.clone();
        for l in &mut scene.lights {
            l.intensity *= k;
        }
        let out = bake(&scene, &s);
        assert!(all_finite(&out), "intensity × {k}: non-finite texels");
        let unscaled: Vec<_> = out
            .pages
            .iter()
            .map(|p| lightbake::lightmap::LightmapPage {
                texels: p.texels.iter().map(|t| *t / k).collect(),
                ..p.clone()
            })
            .collect();
        let diff = relative_rms_error(&unscaled, &reference.pages);
        println!("intensity × {k:e}: relative RMS difference after ÷{k:e}: {diff:.2e}");
        assert!(diff < 1e-4, "intensity × {k}: not linear ({diff:e})");
        let warned = out
            .report
            .warnings
            .iter()
            .any(|w| w.contains("exceeds the half-float range"));
        let max = out
            .pages
            .iter()
            .flat_map(|p| p.texels.iter())
            .fold(0.0f32, |m, t| m.max(t.max_element()));
        assert_eq!(
            warned,
            max > 65504.0,
            "intensity × {k}: brightest texel {max}, warning {warned}"
        );
    }
}

#[test]
fn texels_beyond_half_float_range_are_written_clamped_never_infinite() {
    let mut scene = cornell_box(CornellLight::Point);
    for l in &mut scene.lights {
        l.intensity *= 1e9;
    }
    let mut s = settings(Method::Direct, 16.0);
    s.formats.exr = true;
    s.formats.ktx2 = true;
    let out = bake(&scene, &s);
    assert!(
        out.report
            .warnings
            .iter()
            .any(|w| w.contains("exceeds the half-float range")),
        "{:?}",
        out.report.warnings
    );
    let dir = tempfile::tempdir().unwrap();
    lightbake::output::write_outputs(dir.path(), &out, &scene, None, &s).unwrap();
    let values = exr::prelude::read_first_rgba_layer_from_file(
        dir.path().join("lightmaps/lightmap_0.exr"),
        |_, _| Vec::<f32>::new(),
        |v, _, (r, g, b, _a): (f32, f32, f32, f32)| v.extend([r, g, b]),
    )
    .unwrap()
    .layer_data
    .channel_data
    .pixels;
    assert!(
        values.iter().all(|v| v.is_finite()),
        "the EXR holds a non-finite value"
    );
    let max = values.iter().copied().fold(0.0f32, f32::max);
    assert!(
        (max - 65504.0).abs() < 1.0,
        "the brightest EXR value is {max}, not the half-float maximum"
    );
}
