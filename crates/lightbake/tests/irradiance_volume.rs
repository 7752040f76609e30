//! Irradiance volumes (`lightbake::probes`): open probes against the path tracer at the same
//! points (everything but the lights' direct light, which the engine draws on dynamic
//! objects), probes inside the Cornell box's blocks moved or filled rather than left black,
//! the texture and manifest written for Bevy, the plan's choice of spacing, determinism.

use glam::{Vec2, Vec3};
use lightbake::analysis::points::references;
use lightbake::bake::BakeOutput;
use lightbake::bvh::RayScene;
use lightbake::color::luminance;
use lightbake::probes::gather::{SIDES, Solution};
use lightbake::probes::{IrradianceVolume, ProbeState};
use lightbake::raster::SurfacePoint;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::scene::{LightBake, Scene};
use lightbake::settings::BakeSettings;

mod common;

fn volume_settings(spacing: Option<f32>, rays: u32) -> BakeSettings {
    {
        let mut s = BakeSettings::preview();
        s.volume.enabled = true;
        s.volume.probe_spacing = spacing;
        s.volume.probe_rays = rays;
        // One volume over the scene (the sunlit room's ground would get volumes of its own:
        // `volume_regions.rs`).
        s.volume.regions = 1;
        s
    }
}

/// The one volume of a one-room scene.
fn volume(out: &BakeOutput) -> &IrradianceVolume {
    match &out.irradiance_volumes[..] {
        [v] => v,
        vs => panic!("one volume was wanted, the bake made {}", vs.len()),
    }
}

/// The relative RMS difference between `volume`'s open probes (every `stride`-th) and the
/// path tracer's E/π at their positions, side by side (the reference's own noise taken out),
/// and the reference's relative noise.
fn against_the_path_tracer(scene: &Scene, volume: &IrradianceVolume, stride: usize) -> (f64, f64) {
    // The reference leaves out the direct light of lights baked indirect only: mark them all.
    let mut reference_scene = scene.clone();
    for l in &mut reference_scene.lights {
        l.bake = LightBake::IndirectOnly;
    }
    let rays = RayScene::build(&reference_scene);
    let mut points = Vec::new();
    let mut values = Vec::new();
    for i in (0..volume.grid.len()).step_by(stride) {
        if volume.states[i] != ProbeState::Open {
            continue;
        }
        for (s, d) in SIDES.iter().enumerate() {
            points.push(SurfacePoint {
                position: volume.grid.position(i),
                normal: *d,
                geometric_normal: *d,
                triangle: 0,
                bary: Vec2::ZERO,
            });
            values.push(volume.voxels[i][s]);
        }
    }
    let refs = references(&reference_scene, &rays, &points, 2048, 17);
    let (mut err2, mut ref2, mut var) = (0.0f64, 0.0f64, 0.0f64);
    for (r, v) in refs.iter().zip(&values) {
        let (a, b) = (luminance(*v) as f64, luminance(r.reference) as f64);
        err2 += (a - b).powi(2);
        ref2 += b * b;
        var += r.variance;
    }
    let n = refs.len() as f64;
    let rms = (ref2 / n).sqrt();
    (
        ((err2 - var).max(0.0) / n).sqrt() / rms,
        (var / n).sqrt() / rms,
    )
}

#[test]
fn open_probes_match_the_path_tracer_without_the_lights_direct_light() {
    for (scene, stride, spacing) in [
        (cornell_box(CornellLight::Area), 7, Some(0.06)),
        (cornell_box(CornellLight::Point), 7, Some(0.06)),
        (sunlit_room(), 5, Some(0.5)),
    ] {
        let out = common::bake(&scene, &volume_settings(spacing, 2048));
        let v = volume(&out);
        let (error, noise) = against_the_path_tracer(&scene, v, stride);
        println!(
            "{}: {} probes, volume against the path tracer {:.2}% RMS (reference noise {:.2}%)",
            scene.name,
            v.grid.len(),
            100.0 * error,
            100.0 * noise
        );
        assert!(error < 0.08, "{}: {error}", scene.name);
    }
}

/// Open points next to the probes that sit inside geometry: each open probe beside one, a
/// third of the way towards it, where the volume's trilinear filter gives the closed probe a
/// third of the weight; kept when a gather there meets few back faces.
fn points_beside_closed_probes(v: &IrradianceVolume, solution: &Solution<'_>) -> Vec<Vec3> {
    let r = v.grid.resolution.as_ivec3();
    let mut points = Vec::new();
    for i in 0..v.grid.len() {
        if v.states[i] == ProbeState::Open {
            continue;
        }
        let c = v.grid.coords(i).as_ivec3();
        for d in [
            glam::IVec3::X,
            glam::IVec3::NEG_X,
            glam::IVec3::Z,
            glam::IVec3::NEG_Z,
            glam::IVec3::Y,
        ] {
            let q = c + d;
            if q.cmplt(glam::IVec3::ZERO).any() || q.cmpge(r).any() {
                continue;
            }
            let j = v.grid.index(q.x as u32, q.y as u32, q.z as u32);
            if v.states[j] != ProbeState::Open {
                continue;
            }
            let p = v.grid.position(j).lerp(v.grid.position(i), 1.0 / 3.0);
            if solution.gather(p, 64, 9, u32::MAX, 0.0).back_hits <= 2 {
                points.push(p);
            }
        }
    }
    points
}

#[test]
fn probes_inside_the_blocks_do_not_darken_the_light_beside_them() {
    let scene = cornell_box(CornellLight::Area);
    let out = common::bake(&scene, &volume_settings(Some(0.05), 1024));
    let v = volume(&out);
    let stats = &out.report.irradiance_volumes[0];
    println!("{stats:?}");
    assert!(stats.moved + stats.filled > 0, "{stats:?}");
    assert_eq!(stats.unfilled, 0);
    // A gather stops once its back hits say "inside": where it does not stop it is the full
    // gather's bits, and where the full gather finds the point inside it stops with fewer
    // rays at the same verdict.
    let mut stopped = 0;
    let points = common::with_solution(&out, |solution| {
        for i in 0..v.grid.len() {
            let p = v.grid.position(i);
            let full = solution.gather(p, 256, 7, u32::MAX, 0.0);
            let until = solution.gather(p, 256, 7, 64, 0.0);
            if full.back_hits > 64 {
                assert!(until.stopped && until.back_hits == 65, "{until:?}");
                assert!(until.rays < full.rays, "{} of {}", until.rays, full.rays);
                stopped += 1;
            } else {
                assert_eq!(until, full);
            }
        }
        points_beside_closed_probes(v, solution)
    });
    println!("{stopped} of {} probe centres stop early", v.grid.len());
    assert!(stopped > 0);
    assert!(points.len() >= 10, "{} points", points.len());
    // The path tracer's E/π there, facing up and sideways.
    let normals = [Vec3::Y, Vec3::X, Vec3::NEG_X, Vec3::Z, Vec3::NEG_Z];
    let surface: Vec<SurfacePoint> = points
        .iter()
        .flat_map(|&p| {
            normals.map(|n| SurfacePoint {
                position: p,
                normal: n,
                geometric_normal: n,
                triangle: 0,
                bary: Vec2::ZERO,
            })
        })
        .collect();
    let refs = references(&scene, &RayScene::build(&scene), &surface, 1024, 23);
    let reference: f64 = refs.iter().map(|r| luminance(r.reference) as f64).sum();
    let shown = |v: &IrradianceVolume| -> f64 {
        surface
            .iter()
            .map(|sp| luminance(v.sample(sp.position, sp.normal)) as f64)
            .sum()
    };
    let ratio = shown(v) / reference;
    // The same volume with the closed probes left black, as without moving and filling.
    let mut black = v.clone();
    for (voxel, state) in black.voxels.iter_mut().zip(&v.states) {
        if *state != ProbeState::Open {
            *voxel = [Vec3::ZERO; 6];
        }
    }
    let black_ratio = shown(&black) / reference;
    println!(
        "{} points beside closed probes: volume / path tracer {ratio:.3}; with the closed probes black {black_ratio:.3}",
        points.len()
    );
    assert!((0.9..1.1).contains(&ratio), "{ratio}");
    assert!(
        black_ratio < 0.85,
        "the test sees the closed probes: {black_ratio}"
    );
}

#[test]
fn the_volume_is_written_for_bevy_and_listed_in_the_manifest() {
    let scene = cornell_box(CornellLight::Point);
    let settings = volume_settings(None, 64);
    let out = common::bake(&scene, &settings);
    let v = volume(&out);
    // No spacing given: 16 texels at the scene's 256 texels/m.
    assert!(
        (v.grid.spacing - 16.0 / 256.0).abs() < 1e-6,
        "{}",
        v.grid.spacing
    );
    assert!(out.report.plan.describe().contains("irradiance volume"));
    assert!(out.report.table().contains("irradiance volume 0:"));
    let dir = tempfile::tempdir().unwrap();
    lightbake::write_outputs(dir.path(), &out, &scene, None, &settings).unwrap();
    let bytes = std::fs::read(dir.path().join("irradiance_volumes/volume_0.ktx2")).unwrap();
    let reader = ktx2::Reader::new(&bytes[..]).unwrap();
    let h = reader.header();
    let r = v.grid.resolution;
    assert_eq!(
        (h.pixel_width, h.pixel_height, h.pixel_depth),
        (r.x, 2 * r.y, 3 * r.z)
    );
    assert_eq!(h.format, Some(ktx2::Format::R16G16B16A16_SFLOAT));
    let data = reader.levels().next().unwrap().data;
    let (size, texels) = v.texture();
    assert_eq!(data.len(), texels.len() * 8);
    let k = texels.len() / 3;
    let red = half::f16::from_le_bytes([data[8 * k], data[8 * k + 1]]).to_f32();
    assert!((red - texels[k].x).abs() <= 1e-3 * texels[k].x.max(1.0));
    assert_eq!(size.z, 3 * r.z);
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("manifest.json")).unwrap()).unwrap();
    let entry = &manifest["irradiance_volumes"][0];
    assert_eq!(entry["image"], "irradiance_volumes/volume_0.ktx2");
    let (centre, extent) = v.grid.centre_and_size();
    assert_eq!(entry["center"][1].as_f64().unwrap() as f32, centre.y);
    assert_eq!(entry["size"][0].as_f64().unwrap() as f32, extent.x);
    assert_eq!(entry["intensity"], 1.0);
    assert_eq!(entry["rotation"], serde_json::json!([0.0, 0.0, 0.0, 1.0]));
    assert_eq!(entry["falloff"], serde_json::json!([0.0, 0.0, 0.0]));
}

#[test]
fn an_explicit_spacing_beyond_the_probe_limit_is_refused_by_name() {
    let scene = cornell_box(CornellLight::Point);
    let mut settings = volume_settings(Some(1e-4), 16);
    settings.method = lightbake::settings::Method::Direct;
    let err = lightbake::bake(&scene, &settings, &lightbake::Progress::new()).unwrap_err();
    assert!(err.to_string().contains("probe_spacing"), "{err}");
    settings.volume.probe_spacing = Some(-1.0);
    assert!(
        settings
            .validate()
            .unwrap_err()
            .to_string()
            .contains("probe_spacing")
    );
}

#[test]
fn the_volume_does_not_depend_on_the_thread_count() {
    let scene = cornell_box(CornellLight::Area);
    let mut settings = volume_settings(Some(0.1), 64);
    settings.threads = 1;
    let one = common::bake(&scene, &settings);
    settings.threads = 2;
    let two = common::bake(&scene, &settings);
    assert_eq!(volume(&one), volume(&two));
    let sample = volume(&one).sample(Vec3::splat(0.27), Vec3::Y);
    assert!(sample.is_finite() && sample.max_element() > 0.0);
}
