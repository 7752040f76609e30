//! Unwrap and atlas layout: every baked triangle has TEXCOORD_1 in [0, 1]; rasterised charts do
//! not overlap and keep `padding` empty texels between them; a mesh with its own TEXCOORD_1
//! keeps it.

mod common;

use glam::{Affine3A, Vec3};
use lightbake::bvh::RayScene;
use lightbake::raster::Patches;
use lightbake::scene::Scene;
use lightbake::scene::testscenes::{CornellLight, cornell_box, cuboid, sunlit_room};
use lightbake::settings::BakeSettings;
use lightbake::unwrap::{UvOrigin, overlapping_texels, unwrap_scene};

fn check_layout(scene: &Scene, density: f32, padding: u32) -> usize {
    let settings = {
        let mut s = BakeSettings::default();
        s.layout.padding = padding;
        s
    };
    let layout = unwrap_scene(scene, &settings, density).unwrap();
    layout.validate().unwrap();
    let baked = layout.apply(scene);
    for (m, u) in layout.meshes.iter().enumerate() {
        let Some(u) = u else { continue };
        let mesh = &baked.meshes[m];
        let uv1 = mesh.uv1.as_ref().unwrap();
        // Every triangle's TEXCOORD_1 lies in [0, 1].
        for &i in &mesh.indices {
            let p = uv1[i as usize];
            assert!(
                p.min_element() >= 0.0 && p.max_element() <= 1.0,
                "{}: {p:?}",
                mesh.name
            );
        }
        // No two triangles claim the same texel centre.
        assert_eq!(
            overlapping_texels(mesh, uv1, u.width, u.height),
            0,
            "{}",
            mesh.name
        );
        // Positions are preserved through the seam split.
        let src = &scene.meshes[m];
        for t in 0..src.triangle_count() {
            let (a, b) = (src.triangle(t), mesh.triangle(t));
            for k in 0..3 {
                assert_eq!(src.positions[a[k]], mesh.positions[b[k]]);
            }
        }
    }
    // Charts and instances keep `padding` empty texels between them on every page.
    let rays = RayScene::build(&baked);
    let patches = Patches::build(&baked, &layout, &rays);
    patches.validate(&layout, padding).unwrap();
    patches.patches.len()
}

#[test]
fn shipped_scenes_unwrap_without_overlap_and_with_padding() {
    for padding in [1, 2, 4] {
        assert!(check_layout(&cornell_box(CornellLight::Area), 256.0, padding) > 50_000);
        assert!(check_layout(&sunlit_room(), 16.0, padding) > 10_000);
    }
}

#[test]
fn rotated_and_scaled_instances_share_one_unwrap() {
    let mut s = Scene::default();
    let id = s.add_mesh(cuboid("box", Vec3::ZERO, Vec3::ONE, false));
    for i in 0..5 {
        s.instances.push(lightbake::scene::Instance::new(
            format!("box{i}"),
            id,
            Affine3A::from_scale_rotation_translation(
                Vec3::splat(1.0 + i as f32 * 0.5),
                glam::Quat::from_rotation_y(i as f32),
                Vec3::new(i as f32 * 4.0, 0.0, 0.0),
            ),
        ));
    }
    check_layout(&s, 20.0, 2);
    let layout = unwrap_scene(&s, &BakeSettings::default(), 20.0).unwrap();
    // The largest instance (scale 3) sets the density: a 3 m cube face at 20 texels/m.
    let u = layout.meshes[id].as_ref().unwrap();
    assert!(
        (u.texels_per_metre - 20.0).abs() < 2.0,
        "{}",
        u.texels_per_metre
    );
    let rects: Vec<_> = layout.instances.iter().flatten().collect();
    assert_eq!(rects.len(), 5);
    assert!(
        rects
            .iter()
            .all(|r| r.width == u.width && r.height == u.height)
    );
}

#[test]
fn own_texcoord1_is_kept() {
    let mut s = Scene::default();
    common::add(
        &mut s,
        common::uv_plane("floor", 3.0),
        Vec3::ONE,
        Affine3A::IDENTITY,
        true,
    );
    let layout = unwrap_scene(&s, &BakeSettings::default(), 10.0).unwrap();
    let u = layout.meshes[0].as_ref().unwrap();
    assert_eq!(u.origin, UvOrigin::Existing);
    assert_eq!(&u.uv1, s.meshes[0].uv1.as_ref().unwrap());
    assert_eq!(u.indices, s.meshes[0].indices);
    assert_eq!(u.width, 30);
    // Unless asked to unwrap again.
    let settings = {
        let mut s = BakeSettings::default();
        s.layout.reunwrap = true;
        s
    };
    let layout = unwrap_scene(&s, &settings, 10.0).unwrap();
    assert_eq!(layout.meshes[0].as_ref().unwrap().origin, UvOrigin::Xatlas);
}

/// Triangles of `scene` that the layout squashes (of at least one texel, given less than half
/// the texel density of their mesh) or stretches (an edge over four times the density's length
/// and two texels), measured on each mesh's first baked instance in world space.
fn squashed_triangles(scene: &Scene, settings: &BakeSettings) -> Vec<String> {
    let (density, _) = lightbake::plan::texel_density(scene, settings);
    let layout = unwrap_scene(scene, settings, density).unwrap();
    let baked = layout.apply(scene);
    let mut found = Vec::new();
    for (m, u) in layout.meshes.iter().enumerate() {
        let Some(u) = u else { continue };
        let Some(inst) = baked.instances.iter().find(|i| i.mesh == m && i.bake) else {
            continue;
        };
        let mesh = &baked.meshes[m];
        let uv1 = mesh.uv1.as_ref().unwrap();
        let size = glam::Vec2::new(u.width as f32, u.height as f32);
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh
                .triangle(t)
                .map(|v| inst.transform.transform_point3(mesh.positions[v]));
            let wanted = 0.5 * (b - a).cross(c - a).length() * u.texels_per_metre.powi(2);
            let [p, q, r] = mesh.triangle(t).map(|v| uv1[v] * size);
            let got = 0.5 * (q - p).perp_dot(r - p).abs();
            if wanted >= 1.0 && (got / wanted).sqrt() < 0.5 {
                found.push(format!(
                    "mesh '{}' triangle {t}: {:.1}% of the density",
                    mesh.name,
                    100.0 * (got / wanted).sqrt()
                ));
            }
        }
    }
    found
}

/// No triangle of the real scenes gets less than half its mesh's texel density, nor an edge
/// stretched over four times its length (xatlas squashed a 34 m² ceiling triangle of
/// OpenArena's `oa_bases3` to 1%, and drew a 0.33 m edge of `kaos` across 2 042 texels; such a
/// mesh is charted again with its flat regions projected directly).
#[test]
fn no_triangle_of_the_corpus_is_squashed() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../assets/corpus");
    for file in [
        "house.gltf",
        "kenney_fps/kenney_fps.gltf",
        "openarena/oa_bases3.gltf",
        "openarena/aggressor.gltf",
        "openarena/kaos.gltf",
    ] {
        let scene = lightbake::import_gltf(&root.join(file), lightbake::LightConvention::GltfSpec)
            .unwrap()
            .scene;
        for settings in [BakeSettings::preview(), BakeSettings::medium()] {
            let found = squashed_triangles(&scene, &settings);
            assert!(
                found.is_empty(),
                "{file}: {} squashed: {:?}",
                found.len(),
                &found[..found.len().min(5)]
            );
        }
    }
}
