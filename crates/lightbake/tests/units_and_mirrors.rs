//! A real scene as exporters also write it: in centimetres under a node scaled by 0.01, and
//! mirrored (a negative scale, which flips the triangles' winding: glTF 2.0 §3.5.3,
//! "Instantiation"). Each is scored against the path tracer's references at the original's
//! points (mirrored with it), so a bake that lit a mirrored wall from behind, or that read a
//! tolerance in mesh units, shows as error. And a file authored with mirrored nodes (assimp's
//! `cubes_with_mirroring_and_pivot.fbx`, `assets/corpus/assimp/mirrored_cubes.gltf`), scored
//! against the references of the same surfaces written out unmirrored.

mod common;

use common::corpus_scene;
use glam::{Affine3A, Vec3};
use lightbake::analysis::checks::{measure, verification_points};
use lightbake::scene::{LightKind, Scene};
use lightbake::{BakeOutput, BakeSettings, Progress};

/// The FZK house of the corpus (a real architectural model, not built for these tests).
fn house() -> Scene {
    corpus_scene("house.gltf")
}

/// `scene` with its meshes in centimetres, each instance scaling them by 0.01: the world
/// is unchanged.
fn in_centimetres(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    for mesh in &mut s.meshes {
        for p in &mut mesh.positions {
            *p *= 100.0;
        }
    }
    for inst in &mut s.instances {
        inst.transform *= Affine3A::from_scale(Vec3::splat(0.01));
    }
    s
}

/// The corpus' mirrored cubes: four cubes of an FBX file, two of them under a node scaled by
/// −0.1 in y, on a ground square (`assets/corpus/assimp/`).
fn mirrored_cubes() -> Scene {
    corpus_scene("assimp/mirrored_cubes.gltf")
}

/// Whether an instance's transform mirrors (negative determinant).
fn mirrors(inst: &lightbake::scene::Instance) -> bool {
    inst.transform.matrix3.determinant() < 0.0
}

/// `scene` with every mirrored instance's mesh written out in world space under the
/// identity, its winding reversed so its front stays the same side: the same surfaces and
/// instances in the same order, and no negative determinant.
fn unmirrored(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    for i in 0..s.instances.len() {
        let inst = s.instances[i].clone();
        if !mirrors(&inst) {
            continue;
        }
        let mut mesh = s.meshes[inst.mesh].clone();
        let nm = inst.normal_matrix();
        for p in &mut mesh.positions {
            *p = inst.transform.transform_point3(*p);
        }
        for n in &mut mesh.normals {
            *n = (nm * *n).normalize();
        }
        for t in mesh.indices.chunks_mut(3) {
            t.swap(1, 2);
        }
        s.meshes.push(mesh);
        s.instances[i].mesh = s.meshes.len() - 1;
        s.instances[i].transform = Affine3A::IDENTITY;
    }
    s
}

/// The reflection x → −x.
fn mirror() -> Affine3A {
    Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0))
}

/// `scene` reflected in the plane x = 0, lights and all: every instance gets a negative
/// determinant.
fn mirrored(scene: &Scene) -> Scene {
    let m = mirror();
    let mut s = scene.clone();
    for inst in &mut s.instances {
        inst.transform = m * inst.transform;
    }
    for light in &mut s.lights {
        light.position = m.transform_point3(light.position);
        light.direction = m.transform_vector3(light.direction);
        if let LightKind::Rect { right, .. } = &mut light.kind {
            *right = m.transform_vector3(*right);
        }
    }
    s
}

fn settings() -> BakeSettings {
    let mut s = BakeSettings::preview();
    s.checks.verify_points = 256;
    s.checks.verify_paths = 1024;
    s
}

fn bake(scene: &Scene) -> BakeOutput {
    lightbake::bake(scene, &settings(), &Progress::new()).unwrap()
}

/// Every texel finite, none visible left unlit.
fn sound(name: &str, out: &BakeOutput) {
    assert!(
        out.pages
            .iter()
            .all(|p| p.texels.iter().all(|t| t.is_finite())),
        "{name}: a non-finite texel"
    );
    assert_eq!(out.report.texels.visible_unlit, 0, "{name}");
}

#[test]
fn the_house_in_centimetres_and_mirrored_bakes_as_the_house_does() {
    let scene = house();
    let out = bake(&scene);
    sound("house", &out);
    let points = verification_points(&scene, &out, 256, 1024, 0x51de, 7);
    let base = measure(&scene, &out, &points);
    println!(
        "house: {:.2}% ± {:.2}%",
        100.0 * base.relative_rms,
        100.0 * base.uncertainty
    );
    assert!(base.points >= 250 && base.lit_but_black == 0, "{base:?}");

    let cm = in_centimetres(&scene);
    let cm_out = bake(&cm);
    sound("house in centimetres", &cm_out);
    assert_eq!(
        cm_out.report.plan.texel_density, out.report.plan.texel_density,
        "the density is of the world, not of the mesh units"
    );
    let cm_v = measure(&cm, &cm_out, &points);

    let m = mirror();
    let mirror_points: Vec<_> = points
        .iter()
        .map(|p| {
            let mut q = *p;
            q.position = m.transform_point3(p.position);
            q.normal = m.transform_vector3(p.normal);
            q
        })
        .collect();
    let mirrored_scene = mirrored(&scene);
    let mirrored_out = bake(&mirrored_scene);
    sound("mirrored house", &mirrored_out);
    let mirrored_v = measure(&mirrored_scene, &mirrored_out, &mirror_points);

    for (name, v) in [("centimetres", &cm_v), ("mirrored", &mirrored_v)] {
        println!(
            "{name}: {:.2}% ± {:.2}%, bias {:+.2}%, {} lit but black",
            100.0 * v.relative_rms,
            100.0 * v.uncertainty,
            100.0 * v.relative_bias,
            v.lit_but_black
        );
        assert_eq!(
            v.points, base.points,
            "{name}: a point fell off the lightmap"
        );
        assert_eq!(v.lit_but_black, 0, "{name}: {v:?}");
        // A different unwrap draws the texel grid differently: its error differs by about
        // the check's own spread, not by a wrong side or a wrong tolerance.
        let bound = base.relative_rms + 3.0 * base.uncertainty.max(v.uncertainty) + 0.01;
        assert!(
            v.relative_rms <= bound,
            "{name}: {:.2}% against the house's {:.2}% (bound {:.2}%)",
            100.0 * v.relative_rms,
            100.0 * base.relative_rms,
            100.0 * bound
        );
        assert!(
            v.relative_bias.abs() <= base.relative_bias.abs() + 0.02,
            "{name}: {v:?}"
        );
    }
}

#[test]
fn cubes_authored_mirrored_bake_as_their_unmirrored_copy() {
    let scene = mirrored_cubes();
    assert_eq!(
        scene.instances.iter().filter(|i| mirrors(i)).count(),
        2,
        "the file mirrors Cube2 and its child Cube1"
    );
    // The references come from the copy with no mirror, so they do not depend on how the
    // baker or its path tracer read a negative determinant.
    let flat = unmirrored(&scene);
    let flat_out = bake(&flat);
    sound("unmirrored cubes", &flat_out);
    let points = verification_points(&flat, &flat_out, 512, 1024, 0x51de, 7);
    let base = measure(&flat, &flat_out, &points);
    let on_mirrored = points
        .iter()
        .filter(|p| mirrors(&scene.instances[p.instance as usize]))
        .count();
    println!(
        "unmirrored: {:.2}% ± {:.2}%; {on_mirrored} of {} points on the mirrored cubes",
        100.0 * base.relative_rms,
        100.0 * base.uncertainty,
        points.len()
    );
    assert!(
        on_mirrored >= 10,
        "{on_mirrored} points on the mirrored cubes"
    );
    assert_eq!(base.lit_but_black, 0, "{base:?}");

    let out = bake(&scene);
    sound("mirrored cubes", &out);
    let v = measure(&scene, &out, &points);
    println!(
        "as authored: {:.2}% ± {:.2}%, bias {:+.2}%, {} lit but black",
        100.0 * v.relative_rms,
        100.0 * v.uncertainty,
        100.0 * v.relative_bias,
        v.lit_but_black
    );
    assert_eq!(v.points, base.points, "a point fell off the lightmap");
    assert_eq!(v.lit_but_black, 0, "{v:?}");
    let bound = base.relative_rms + 3.0 * base.uncertainty.max(v.uncertainty) + 0.01;
    assert!(v.relative_rms <= bound, "{v:?} against {base:?}");
}
