//! The same input gives the same bits whatever the thread count: random numbers are indexed by
//! texel, sample and seed, and every sum runs in a fixed order.

mod common;

use lightbake::output::write_outputs;
use lightbake::progress::Progress;
use lightbake::scene::gltf_import::import_gltf;
use lightbake::scene::gltf_write::write_scene_gltf;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::{BakeSettings, LightConvention};

fn settings(threads: usize, density: f32) -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.layout.texel_density = Some(density);
    s.layout.texel_density_from_scene = false;
    s.threads = threads;
    s.formats.ktx2 = true;
    s
}

#[test]
fn one_and_two_threads_write_identical_lightmap_bytes() {
    let dir = tempfile::tempdir().unwrap();
    for (scene, density) in [
        (cornell_box(CornellLight::Area), 96.0),
        (cornell_box(CornellLight::Point), 96.0),
        (sunlit_room(), 8.0),
    ] {
        let path = dir.path().join(format!("{}.gltf", scene.name));
        write_scene_gltf(&scene, &path).unwrap();
        let imported = import_gltf(&path, LightConvention::GltfSpec).unwrap();
        let mut files = Vec::new();
        for threads in [1, 2, 2] {
            let s = settings(threads, density);
            let out = lightbake::bake(&imported.scene, &s, &Progress::new()).unwrap();
            assert_eq!(out.report.threads, threads);
            let out_dir = dir
                .path()
                .join(format!("{}_{threads}_{}", scene.name, files.len()));
            write_outputs(&out_dir, &out, &imported.scene, Some(&imported.source), &s).unwrap();
            let mut bytes = Vec::new();
            for ext in ["exr", "ktx2"] {
                bytes.push(
                    std::fs::read(out_dir.join(format!("lightmaps/lightmap_0.{ext}"))).unwrap(),
                );
            }
            bytes.push(std::fs::read(out_dir.join(format!("{}.bin", scene.name))).unwrap());
            files.push(bytes);
        }
        assert!(
            files[0] == files[1],
            "{}: 1 and 2 threads differ",
            scene.name
        );
        assert!(
            files[1] == files[2],
            "{}: two runs with 2 threads differ",
            scene.name
        );
    }
}

#[test]
fn every_method_and_solver_gives_the_same_bits_on_1_and_2_threads() {
    use lightbake::settings::Basis;
    use lightbake::settings::Method;
    let scene = cornell_box(CornellLight::Area);
    let base = {
        let mut s = BakeSettings::preview();
        s.layout.texel_density = Some(24.0);
        s.layout.texel_density_from_scene = false;
        s
    };
    let mut cases: Vec<(String, BakeSettings)> = Vec::new();
    for method in [Method::Direct, Method::Vpl, Method::Hybrid] {
        cases.push((
            format!("{method:?}"),
            BakeSettings {
                method,
                ..base.clone()
            },
        ));
    }
    cases.push(("hybrid, bias compensation".into(), {
        let mut s = base.clone();
        s.method = Method::Hybrid;
        s.vpl.bias_compensation = true;
        s
    }));
    for solver in common::ALL_SOLVERS {
        cases.push((format!("radiosity {}", solver.name()), {
            let mut s = base.clone();
            s.method = Method::Radiosity;
            s.radiosity.solver = solver;
            s
        }));
    }
    cases.push(("radiosity, constant basis".into(), {
        let mut s = base.clone();
        s.method = Method::Radiosity;
        s.radiosity.basis = Basis::Constant;
        s
    }));
    cases.push((
        "radiosity, target error 5%".into(),
        BakeSettings {
            method: Method::Radiosity,
            target_error: Some(0.05),
            ..base.clone()
        },
    ));
    for (name, s) in cases {
        let bits = |threads: usize| -> Vec<u32> {
            let s = BakeSettings {
                threads,
                ..s.clone()
            };
            let out = lightbake::bake(&scene, &s, &Progress::new())
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            out.pages
                .iter()
                .flat_map(|p| p.texels.iter())
                .flat_map(|t| t.to_array().map(f32::to_bits))
                .collect()
        };
        let one = bits(1);
        assert!(one.iter().any(|&b| b != 0), "{name}: black lightmap");
        assert!(one == bits(2), "{name}: 1 and 2 threads differ");
    }
}
