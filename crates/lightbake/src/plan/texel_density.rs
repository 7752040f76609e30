//! The texel density: from the settings, the scene's hint, or the texel budget spread over
//! the baked surface.

use crate::scene::Scene;
use crate::settings::BakeSettings;

/// The texel density a bake of `scene` with `settings` uses (texels per metre), and where it
/// came from: the settings, the scene's hint, or the texel budget spread over the baked
/// surface (so a scene in millimetres, metres or kilometres gets the same layout).
pub fn texel_density(scene: &Scene, settings: &BakeSettings) -> (f32, String) {
    if let Some(d) = settings.layout.texel_density {
        return (d, "settings (layout.texel_density)".to_string());
    }
    if let Some(d) = scene_hint(scene, settings) {
        return (
            d,
            "the scene's hint (extras.lightbake.texel_density)".to_string(),
        );
    }
    // Covered texels ≈ Σ area × (density × scale)².
    let area = covered_area(scene);
    if !(area > 0.0 && area.is_finite()) {
        return (1.0, "no baked surface: any density".to_string());
    }
    let budget = settings.layout.texel_budget as f64;
    let density = (budget / area).sqrt().clamp(1e-9, 1e9) as f32;
    (
        density,
        format!(
            "a budget of {} texels over {} of baked surface",
            settings.layout.texel_budget,
            format_area(area)
        ),
    )
}

/// The scene's density hint, when it has a usable one and the settings take it.
fn scene_hint(scene: &Scene, settings: &BakeSettings) -> Option<f32> {
    scene
        .texel_density_hint
        .filter(|d| settings.layout.texel_density_from_scene && d.is_finite() && *d > 0.0)
}

/// Whether the density comes from the texel budget (neither the settings nor the scene set
/// it).
pub fn density_from_budget(scene: &Scene, settings: &BakeSettings) -> bool {
    settings.layout.texel_density.is_none() && scene_hint(scene, settings).is_none()
}

/// The baked surfaces' area, each instance's weighted by its density scale squared, m².
pub(super) fn covered_area(scene: &Scene) -> f64 {
    scene
        .instances
        .iter()
        .enumerate()
        .filter(|(_, inst)| inst.bake)
        .map(|(i, inst)| {
            let scale = inst.texel_density_scale as f64;
            scene.instance_area(i) as f64 * scale * scale
        })
        .sum()
}

/// A density to four significant digits (whole numbers as they are).
pub fn density_text(d: f32) -> String {
    if d == d.round() && d.abs() < 1e7 {
        return format!("{d:.0}");
    }
    let digits = 3 - d.abs().log10().floor() as i32;
    if (0..=12).contains(&digits) {
        format!("{d:.*}", digits as usize)
    } else {
        format!("{d:.3e}")
    }
}

/// An area in the unit that reads best (m², mm², km²).
fn format_area(area: f64) -> String {
    if area < 1e-2 {
        format!("{:.4} mm²", area * 1e6)
    } else if area > 1e6 {
        format!("{:.4} km²", area * 1e-6)
    } else {
        format!("{area:.4} m²")
    }
}
