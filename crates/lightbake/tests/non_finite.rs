//! No non-finite value reaches an output: a NaN planted in the output of each checked stage
//! (`lightbake::bake::inject_nan`) stops the bake with an internal error naming that stage and
//! the texel, and the writer refuses a page holding one. The tests share the injection switch,
//! so they run one after another.

use std::sync::Mutex;

use lightbake::bake::inject_nan;
use lightbake::progress::Progress;
use lightbake::scene::testscenes::{CornellLight, cornell_box};
use lightbake::settings::{BakeSettings, SolverChoice};
use lightbake::{BakeError, write_outputs};

static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());

/// Medium at 16 texels/m, the hierarchical solve (per-texel noise for the denoiser), an
/// irradiance volume: every checked stage runs.
fn settings() -> BakeSettings {
    let mut s = BakeSettings::medium();
    s.layout.texel_density = Some(16.0);
    s.layout.texel_density_from_scene = false;
    s.radiosity.solver = SolverChoice::Hierarchical;
    s.volume.enabled = true;
    s.volume.probe_spacing = Some(0.1);
    s.volume.probe_rays = 32;
    s
}

#[test]
fn a_nan_in_any_stage_stops_the_bake_naming_the_stage() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let scene = cornell_box(CornellLight::Area);
    for stage in [
        "indirect",
        "lighting",
        "denoise",
        "contact fit",
        "dilate",
        "stitch",
        "volume",
    ] {
        inject_nan(Some(stage));
        let result = lightbake::bake(&scene, &settings(), &Progress::new());
        inject_nan(None);
        match result {
            Err(e @ BakeError::NonFinite { .. }) => {
                let text = e.to_string();
                assert!(text.contains(&format!("the {stage} stage")), "{text}");
                assert!(text.contains("NaN"), "{text}");
                assert!(text.contains("texel") || text.contains("probe"), "{text}");
            }
            Err(e) => panic!("{stage}: another error: {e}"),
            Ok(_) => panic!("{stage}: the planted NaN went through"),
        }
    }
    // Nothing planted: the same bake is finite and succeeds.
    let out = lightbake::bake(&scene, &settings(), &Progress::new()).unwrap();
    assert!(
        out.pages
            .iter()
            .all(|p| p.texels.iter().all(|t| t.is_finite()))
    );
}

#[test]
fn the_writer_refuses_a_page_holding_a_nan_and_writes_nothing() {
    let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
    let scene = cornell_box(CornellLight::Area);
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(8.0);
    s.layout.texel_density_from_scene = false;
    let mut out = lightbake::bake(&scene, &s, &Progress::new()).unwrap();
    out.pages[0].texels[7] = glam::Vec3::new(f32::INFINITY, 0.0, 0.0);
    let dir = tempfile::tempdir().unwrap();
    let err = write_outputs(dir.path(), &out, &scene, None, &s).unwrap_err();
    assert!(err.to_string().contains("non-finite"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}
