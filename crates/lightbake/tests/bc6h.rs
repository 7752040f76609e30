//! BC6H pages (`--format ktx2-bc6h`): the layout keeps every 4×4 block to one chart of one
//! instance, whichever way the mesh was charted; the file is what the page holds within the
//! encoder's error, and the bytes do not depend on the thread count.

mod common;

use std::collections::HashMap;

use glam::{Affine3A, Vec2, Vec3};
use lightbake::output::{bc6h, write_outputs};
use lightbake::progress::Progress;
use lightbake::raster::Patches;
use lightbake::scene::testscenes::office::uv_sphere;
use lightbake::scene::testscenes::{CornellLight, cornell_box, cuboid, sunlit_room};
use lightbake::scene::{Instance, Scene};
use lightbake::settings::BakeSettings;
use lightbake::unwrap::{Layout, UvOrigin, unwrap_scene};

fn settings(threads: usize, density: Option<f32>) -> BakeSettings {
    let mut s = BakeSettings::preview();
    if let Some(d) = density {
        s.layout.texel_density = Some(d);
        s.layout.texel_density_from_scene = false;
    }
    s.threads = threads;
    s.formats.ktx2_bc6h = true;
    s
}

/// The first 4×4 block holding texels that bilinear filtering reads on two charts or two
/// instances (found by sampling each triangle every quarter texel or closer, weights below
/// 1/1000 left out), if any.
fn blocks_read_by_two_charts(scene: &Scene, layout: &Layout) -> Option<String> {
    let mut owner: HashMap<(u32, i64, i64), (usize, u32)> = HashMap::new();
    for (i, rect) in layout.instances.iter().enumerate() {
        let Some(r) = rect else { continue };
        let Some(u) = &layout.meshes[scene.instances[i].mesh] else {
            continue;
        };
        let size = Vec2::new(u.width as f32, u.height as f32);
        let corner = Vec2::new(r.x as f32, r.y as f32);
        for (t, &chart) in u.triangle_charts.iter().enumerate() {
            if chart == u32::MAX {
                continue;
            }
            let [a, b, c] = [0, 1, 2].map(|k| u.uv1[u.indices[3 * t + k] as usize] * size + corner);
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            let n = (4.0 * longest).ceil() as usize + 2;
            for j in 0..=n {
                for k in 0..=n - j {
                    let p = a + (b - a) * (j as f32 / n as f32) + (c - a) * (k as f32 / n as f32);
                    let q = p - Vec2::splat(0.5);
                    let (f, w) = (q.floor(), q - q.floor());
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        // A weight below 1/1000 (a vertex a rounding off a texel centre)
                        // is not a read.
                        let wx = if dx == 1 { w.x } else { 1.0 - w.x };
                        let wy = if dy == 1 { w.y } else { 1.0 - w.y };
                        if wx < 1e-3 || wy < 1e-3 {
                            continue;
                        }
                        let (x, y) = (f.x as i64 + dx, f.y as i64 + dy);
                        let block = (r.page, x.div_euclid(4), y.div_euclid(4));
                        let first = *owner.entry(block).or_insert((i, chart));
                        if first != (i, chart) {
                            return Some(format!(
                                "{}: the block at ({}, {}) of page {} is read by (instance, chart) {first:?} and {:?}",
                                scene.name,
                                4 * block.1,
                                4 * block.2,
                                r.page,
                                (i, chart)
                            ));
                        }
                    }
                }
            }
        }
    }
    None
}

/// Asserts [`blocks_read_by_two_charts`] finds no block.
fn assert_blocks_hold_one_chart(scene: &Scene, layout: &Layout) {
    if let Some(problem) = blocks_read_by_two_charts(scene, layout) {
        panic!("{problem}");
    }
}

/// Bakes and writes `scene`; returns the BC6H files' bytes and what the writer measured.
fn bake_bc6h(scene: &Scene, s: &BakeSettings) -> (Vec<Vec<u8>>, Vec<bc6h::Bc6hError>) {
    let out = lightbake::bake(scene, s, &Progress::new()).unwrap();
    for (i, rect) in out.layout.instances.iter().enumerate() {
        if let Some(r) = rect {
            assert!(
                r.x % 4 == 0 && r.y % 4 == 0,
                "{}: instance {i} starts at ({}, {}), not on a block",
                scene.name,
                r.x,
                r.y
            );
        }
    }
    for p in &out.layout.pages {
        assert!(p.width % 4 == 0 && p.height % 4 == 0, "{p:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    let written = write_outputs(dir.path(), &out, scene, None, s).unwrap();
    let bytes: Vec<Vec<u8>> = (0..out.pages.len())
        .map(|i| {
            std::fs::read(dir.path().join(format!("lightmaps/lightmap_{i}.bc6h.ktx2"))).unwrap()
        })
        .collect();
    assert_eq!(written.bc6h.len(), out.pages.len());
    assert_blocks_hold_one_chart(scene, &out.layout);
    for (i, (page, b)) in out.pages.iter().zip(&bytes).enumerate() {
        // The file holds the page's blocks: an eighth of Rgba16Float's bytes, plus the header.
        let blocks = (page.width / 4 * page.height / 4) as usize;
        assert!(
            b.len() >= blocks * 16 && b.len() < blocks * 16 + 1024,
            "{}",
            b.len()
        );
        assert_eq!(bc6h::measure(page, b).unwrap(), written.bc6h[i]);
    }
    (bytes, written.bc6h)
}

#[test]
fn bc6h_pages_keep_each_block_to_one_instance_and_stay_within_the_encoders_error() {
    for (scene, density) in [
        (cornell_box(CornellLight::Point), Some(64.0)),
        (sunlit_room(), Some(16.0)),
        (
            common::corpus_scene("kenney_platformer/kenney_platformer.gltf"),
            None,
        ),
    ] {
        let (_, errors) = bake_bc6h(&scene, &settings(2, density));
        for (i, e) in errors.iter().enumerate() {
            println!("{}: {}", scene.name, e.summary(i));
            assert!(e.rms_relative < 0.03, "{}: {e:?}", scene.name);
            assert!(e.texels > 0);
        }
    }
}

#[test]
fn bc6h_bytes_do_not_depend_on_the_thread_count() {
    let scene = sunlit_room();
    let (one, _) = bake_bc6h(&scene, &settings(1, Some(8.0)));
    let (two, _) = bake_bc6h(&scene, &settings(2, Some(8.0)));
    assert!(one == two, "1 and 2 threads wrote different BC6H pages");
}

#[test]
fn every_way_of_charting_keeps_each_block_to_one_chart() {
    // xatlas' own charts at one density (no rescaling: the bake's density pass is not run),
    // the charts of a big curved mesh unwrapped in pieces, and many instances of a box.
    let mut pieces = Scene {
        name: "sphere in pieces".into(),
        ..Scene::default()
    };
    let ball = pieces.add_mesh(uv_sphere("ball", 1.0, 48, 64));
    let boxed = pieces.add_mesh(cuboid("box", Vec3::ZERO, Vec3::ONE, false));
    pieces
        .instances
        .push(Instance::new("ball", ball, Affine3A::IDENTITY));
    for k in 0..6 {
        let at = Vec3::new(3.0 + k as f32 * 1.5, 0.0, 0.0);
        pieces.instances.push(Instance::new(
            format!("box{k}"),
            boxed,
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.3 + 0.2 * k as f32),
                glam::Quat::IDENTITY,
                at,
            ),
        ));
    }
    assert!(pieces.meshes[ball].triangle_count() > 4096);
    for (scene, density) in [
        (common::corpus_scene("kenney_fps/kenney_fps.gltf"), 16.0),
        (common::corpus_scene("assimp/teapots.gltf"), 24.0),
        (pieces, 40.0),
    ] {
        // At the default padding and others: the charts keep the padding between them.
        for padding in [2, 1, 3, 4] {
            let mut s = settings(2, None);
            s.layout.padding = padding;
            let layout = unwrap_scene(&scene, &s, density).unwrap();
            layout.validate().unwrap();
            assert_blocks_hold_one_chart(&scene, &layout);
            let baked = layout.apply(&scene);
            let rays = lightbake::bvh::RayScene::build(&baked);
            Patches::build(&baked, &layout, &rays)
                .validate(&layout, padding)
                .unwrap_or_else(|e| panic!("{} at padding {padding}: {e}", scene.name));
        }
    }
}

#[test]
fn a_meshs_own_lightmap_uvs_are_moved_onto_blocks_by_whole_texels() {
    // The Kenney FPS level with its default pages' UVs as its own TEXCOORD_1: a level baked
    // once and committed with its lightmap UVs, baked again for BC6H pages.
    let level = common::corpus_scene("kenney_fps/kenney_fps.gltf");
    let mut plain = settings(2, None);
    plain.formats.ktx2_bc6h = false;
    let own = unwrap_scene(&level, &plain, 16.0).unwrap().apply(&level);
    assert!(own.meshes.iter().all(|m| m.uv1.is_some()));
    // Kept as they are, its charts share blocks (the check sees it).
    let kept = unwrap_scene(&own, &plain, 16.0).unwrap();
    let shared = blocks_read_by_two_charts(&own, &kept);
    println!("kept as they are: {shared:?}");
    assert!(shared.is_some());
    // For BC6H pages each chart is moved onto blocks of its own, by whole texels: its
    // sampling is unchanged.
    let s = settings(2, None);
    let layout = unwrap_scene(&own, &s, 16.0).unwrap();
    layout.validate().unwrap();
    assert_blocks_hold_one_chart(&own, &layout);
    let baked = layout.apply(&own);
    let rays = lightbake::bvh::RayScene::build(&baked);
    Patches::build(&baked, &layout, &rays)
        .validate(&layout, s.layout.padding)
        .unwrap();
    let size = |w: u32, h: u32| Vec2::new(w as f32, h as f32);
    let mut charts = 0;
    for (moved, kept) in layout.meshes.iter().zip(&kept.meshes) {
        let (Some(u), Some(k)) = (moved, kept) else {
            continue;
        };
        assert_eq!(u.origin, UvOrigin::Existing);
        let xref = u.xref.as_ref().expect("moved vertices");
        let mut shifts: HashMap<u32, Vec2> = HashMap::new();
        for (t, &chart) in u.triangle_charts.iter().enumerate() {
            for c in 0..3 {
                let v = u.indices[3 * t + c] as usize;
                let d = u.uv1[v] * size(u.width, u.height)
                    - k.uv1[xref[v] as usize] * size(k.width, k.height);
                assert!((d - d.round()).abs().max_element() < 2e-3, "{d}");
                let first = *shifts.entry(chart).or_insert(d.round());
                assert_eq!(first, d.round(), "chart {chart} moved two ways");
            }
        }
        charts += shifts.len();
    }
    println!("{charts} charts moved");
    assert!(charts > 100);
    // Hundreds of small charts, each rounded up to whole blocks: the warning says how much
    // larger they are and suggests a new unwrap.
    let texels = |l: &Layout| -> u64 {
        (l.meshes.iter().flatten())
            .map(|u| u64::from(u.width) * u64::from(u.height))
            .sum()
    };
    let growth = texels(&layout) as f64 / texels(&kept) as f64;
    println!("{growth:.2}× the texels; {:?}", layout.warnings);
    assert!(growth > 1.5);
    assert!(
        layout
            .warnings
            .iter()
            .any(|w| w.contains(&format!("{growth:.2}×")) && w.contains("--reunwrap")),
        "{:?}",
        layout.warnings
    );
}
