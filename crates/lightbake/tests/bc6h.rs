//! BC6H pages (`--format ktx2-bc6h`): the layout keeps every 4×4 block to one instance, the
//! file is what the page holds within the encoder's error, and the bytes do not depend on the
//! thread count.

mod common;

use lightbake::output::{bc6h, write_outputs};
use lightbake::progress::Progress;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, sunlit_room};
use lightbake::settings::BakeSettings;

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
    // No block reads texels of two instances (each instance's rectangle starts on a block and
    // the next one starts on the first block past its padding).
    for (pi, page) in out.pages.iter().enumerate() {
        let w = page.width as usize;
        let mut owner = vec![usize::MAX; page.texels.len()];
        for (i, r) in out.layout.instances.iter().enumerate() {
            let Some(r) = r.filter(|r| r.page as usize == pi) else {
                continue;
            };
            for y in r.y..r.y + r.height {
                for x in r.x..r.x + r.width {
                    owner[y as usize * w + x as usize] = i;
                }
            }
        }
        let read = bc6h::read_mask(page);
        for by in (0..page.height as usize).step_by(4) {
            for bx in (0..w).step_by(4) {
                let mut owners: Vec<usize> = (by..by + 4)
                    .flat_map(|y| (bx..bx + 4).map(move |x| y * w + x))
                    .filter(|&k| read[k] && owner[k] != usize::MAX)
                    .map(|k| owner[k])
                    .collect();
                owners.sort_unstable();
                owners.dedup();
                assert!(
                    owners.len() <= 1,
                    "{}: the block at ({bx}, {by}) of page {pi} reads instances {owners:?}",
                    scene.name
                );
            }
        }
    }
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
