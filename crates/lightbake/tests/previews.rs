//! Progressive previews (`lightbake::bake::preview`): a bake that is asked for them publishes
//! the direct light, then the first indirect solution with its ambient term, then the final
//! pages; they are finite, brighten from one to the next and end at the bake's own result.

use std::sync::{Arc, Mutex};

use lightbake::bake::{BakeBuilder, PreviewKind, PreviewSlot};
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, Method, SolverChoice};

/// (kind, sequence, mean E/π luminance over covered texels, all finite, ambient luminance).
type Seen = (PreviewKind, u32, f64, bool, f32);

fn mean(pages: &[lightbake::LightmapPage]) -> (f64, bool) {
    let (mut sum, mut n, mut finite) = (0.0f64, 0usize, true);
    for p in pages {
        for (t, &c) in p.texels.iter().zip(&p.covered) {
            finite &= t.is_finite();
            if c {
                sum += (0.2126 * t.x + 0.7152 * t.y + 0.0722 * t.z) as f64;
                n += 1;
            }
        }
    }
    (sum / n.max(1) as f64, finite)
}

fn previews_of(scene: &Scene, settings: &BakeSettings) -> (Vec<Seen>, f64) {
    let seen: Arc<Mutex<Vec<Seen>>> = Arc::default();
    let sink = Arc::clone(&seen);
    let slot = Arc::new(PreviewSlot::observed(move |p| {
        let (m, finite) = mean(&p.pages);
        let ambient = 0.2126 * p.ambient.x + 0.7152 * p.ambient.y + 0.0722 * p.ambient.z;
        sink.lock()
            .unwrap()
            .push((p.kind, p.sequence, m, finite, ambient));
    }));
    let out = BakeBuilder::new(scene.clone())
        .settings(settings.clone())
        .previews(Arc::clone(&slot))
        .run()
        .unwrap();
    let last = slot.latest().unwrap();
    assert_eq!(last.kind, PreviewKind::Final);
    assert_eq!(
        last.pages, out.pages,
        "the final preview is the bake's result"
    );
    assert_eq!(*last.layout, out.layout);
    let seen = seen.lock().unwrap().clone();
    (seen, mean(&out.pages).0)
}

fn check_brightening(name: &str, seen: &[Seen], final_mean: f64) {
    println!("{name}: {seen:?}, final {final_mean:.4}");
    let kinds: Vec<PreviewKind> = seen.iter().map(|s| s.0).collect();
    assert_eq!(
        kinds,
        [
            PreviewKind::Direct,
            PreviewKind::Indirect,
            PreviewKind::Final
        ],
        "{name}"
    );
    assert_eq!(seen.iter().map(|s| s.1).collect::<Vec<_>>(), [1, 2, 3]);
    assert!(seen.iter().all(|s| s.3), "{name}: a preview is not finite");
    let (direct, indirect) = (seen[0].2, seen[1].2);
    assert!(direct < indirect, "{name}: {direct} then {indirect}");
    assert!(
        indirect <= 1.05 * final_mean,
        "{name}: the indirect preview {indirect} overshoots the final {final_mean}"
    );
    assert!(
        (indirect - final_mean).abs() < (direct - final_mean).abs(),
        "{name}: each preview is closer to the final bake"
    );
}

#[test]
fn hierarchical_previews_brighten_towards_the_final_bake() {
    for scene in [cornell_box(CornellLight::Area), sunlit_room()] {
        let settings = BakeSettings::preview();
        let (seen, final_mean) = previews_of(&scene, &settings);
        check_brightening(&scene.name, &seen, final_mean);
    }
}

#[test]
fn matrix_solve_previews_carry_the_ambient_term_of_its_residual() {
    let scene = cornell_box(CornellLight::Point);
    let mut settings = BakeSettings::preview();
    settings.layout.texel_density = Some(48.0);
    settings.layout.texel_density_from_scene = false;
    settings.radiosity.solver = SolverChoice::Jacobi;
    let (seen, converged) = previews_of(&scene, &settings);
    check_brightening("cornell_box_point, Jacobi", &seen, converged);
    assert!(
        seen[1].4.abs() < 1e-2 * seen[1].2 as f32,
        "a solved system leaves no ambient term: {seen:?}"
    );
    // Stopped after two sweeps, the solve leaves energy undistributed; the preview's
    // ambient term stands in for it and brings the preview closer to the converged bake than
    // the truncated bake itself is.
    settings.radiosity.max_solver_iterations = 2;
    let (seen, truncated) = previews_of(&scene, &settings);
    println!("two sweeps: {seen:?}, truncated final {truncated:.4}, converged {converged:.4}");
    assert!(seen[1].4 > 0.0, "no ambient term: {seen:?}");
    assert!(
        (seen[1].2 - converged).abs() < (truncated - converged).abs(),
        "{seen:?}: truncated {truncated}, converged {converged}"
    );
}

#[test]
fn a_direct_bake_previews_direct_then_final_and_a_plain_bake_none() {
    let scene = cornell_box(CornellLight::Point);
    let settings = BakeSettings {
        method: Method::Direct,
        ..BakeSettings::preview()
    };
    let (seen, _) = previews_of(&scene, &settings);
    let kinds: Vec<PreviewKind> = seen.iter().map(|s| s.0).collect();
    assert_eq!(kinds, [PreviewKind::Direct, PreviewKind::Final]);
    let slot = Arc::new(PreviewSlot::default());
    BakeBuilder::new(scene)
        .settings(settings)
        .previews(Arc::clone(&slot))
        .run()
        .unwrap();
    assert!(slot.latest().is_none(), "previews only when asked for");
}
